"""Contact spans: when each pair of pieces touches, read from a result's event log."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from packbot.keywords import checked_arguments
from packbot.result import SimResult

__all__ = ["ContactSpan", "contact_spans"]


@checked_arguments
@dataclass(frozen=True)
class ContactSpan:
    """A time span over which a pair of pieces is in contact.

    Attributes:
        link1: Body 1 of the pair (distal link).
        link2: Body 2 (proximal link, chassis or obstacle).
        piece1: Convex piece on body 1.
        piece2: Convex piece on body 2.
        start: Time of the impact [s].
        end: Time of the release, or the end of the result [s].
    """

    link1: str
    link2: str
    piece1: str
    piece2: str
    start: float
    end: float

    @property
    def key(self) -> tuple[str, str, str, str]:
        """(link1, link2, piece1, piece2)."""
        return (self.link1, self.link2, self.piece1, self.piece2)


@checked_arguments
def contact_spans(result: SimResult) -> list[ContactSpan]:
    """The contact spans of a result's event log, in order of start.

    Each runs from an ``impact`` of a pair of pieces to the next ``release`` of that pair, or
    to the end of the result. A ``release`` that names joints is a clamp's (the report's law
    released the clamp of a joint moving away; the pair stays in contact): it ends no span.
    """
    end = float(result.t[-1]) if len(result.t) else 0.0
    open_: dict[tuple[str, str, str, str], float] = {}
    spans: list[ContactSpan] = []
    for e in result.events:
        key = (e.link1, e.link2, e.piece1, e.piece2)
        if e.kind == "impact" and e.piece1 and e.piece2:
            open_.setdefault(key, e.t)
        elif e.kind == "release" and key in open_ and not e.relevant_joints:
            spans.append(ContactSpan(*key, start=open_.pop(key), end=e.t))
    spans += [ContactSpan(*key, start=t, end=end) for key, t in open_.items()]
    return sorted(spans, key=lambda s: s.start)


def _merge(spans: Sequence[ContactSpan]) -> list[ContactSpan]:
    """Union of spans as spans (their pair fields are those of the first of each union)."""
    out: list[ContactSpan] = []
    for s in sorted(spans, key=lambda s: s.start):
        if out and s.start <= out[-1].end:
            last = out[-1]
            out[-1] = ContactSpan(*last.key, start=last.start, end=max(last.end, s.end))
        else:
            out.append(s)
    return out
