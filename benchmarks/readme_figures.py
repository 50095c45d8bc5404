"""Regenerate the README's figures: the collapse plots and a still of its browser animation.

Run by hand from the repository root (needs Debian's ``chromium`` for the still)::

    python benchmarks/readme_figures.py [--time 0.6]

It runs ``packbot run collapse --out docs/figures --plot --html --overwrite`` (the plots
``collapse_{joints,distance,energy}`` as PNG + SVG, and ``collapse.html``), then screenshots the
page headless at ``--time`` seconds into ``docs/figures/collapse_animation.png`` (the chromium
command line of ``tests/test_viz.py``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path

from packbot.cli import main as packbot_main
from packbot.viz.html import screenshot_command

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--time", type=float, default=0.6, help="animation time of the still [s]")
    args = parser.parse_args()
    argv = ["run", "collapse", "--out", str(FIGURES), "--plot", "--html", "--overwrite"]
    code = packbot_main(argv)
    if code:
        return code
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        print("chromium not found: the animation still was not regenerated")
        return 1
    page = FIGURES / "collapse.html"
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run(
            screenshot_command(
                browser,
                f"{page.as_uri()}#t={args.time:.3f}",
                FIGURES / "collapse_animation.png",
                profile,
            ),
            check=True,
            capture_output=True,
            timeout=120,
        )
    print(f"wrote {FIGURES / 'collapse_animation.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
