"""Labels of the event log for figures and pages: an event's kind and its joint or pair.

Shared by the plots (:mod:`packbot.plots`) and the HTML animation (:mod:`packbot.viz.html`);
it imports nothing heavy.
"""

from __future__ import annotations

from packbot.result import Event

__all__ = ["event_label", "plain_text"]


def event_label(event: Event) -> str:
    """The label of an event in the plots and pages: its kind and its joint or pair.

    ``"impact link3\u2013link1"`` (the pair's bodies, an en dash between them), ``"limit elbow1
    upper"``, ``"failure: elbow1 frozen"`` (the joint and the failure's kind), ``"freeze
    elbow1"``, ``"release elbow1 upper"`` (a limit stop let go), ``"slip shoulder"``.

    Args:
        event: An entry of a result's event log.

    Returns:
        The label, one line.
    """
    kind, a, b = event.kind, event.link1, event.link2
    if kind == "failure":
        return f"failure: {a} {b}".rstrip() if a else "failure"
    if kind == "limit":
        return " ".join(s for s in ("limit", a, b) if s)
    if b in ("upper", "lower"):  # a limit stop's release
        return f"{kind} {a} {b}"
    if a and b:
        return f"{kind} {a}\u2013{b}"
    return f"{kind} {a}".rstrip()


def plain_text(text: str) -> str:
    """Text for a matplotlib label drawn as it is: ``$`` escaped (no mathtext).

    A name holding two ``$`` (a scenario named ``x$_$y``) would otherwise be parsed as TeX
    math, and fail to draw.
    """
    return text.replace("$", "\\$")
