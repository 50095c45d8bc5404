"""Start-up: ``import packbot`` and a flagless run leave the heavy optional modules unloaded.

Each check runs in a fresh interpreter (a subprocess) and inspects ``sys.modules``; nothing is
timed.
"""

from __future__ import annotations

import json
import math
import random
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from scipy.optimize import brentq as scipy_brentq

from packbot.errors import ConfigurationError
from packbot.ode import brentq

HEAVY = ("matplotlib", "meshcat", "scipy.spatial", "scipy.optimize", "packbot.urdfgen")


def _loaded_after(code: str) -> dict[str, bool]:
    report = f"print(json.dumps({{m: m in sys.modules for m in {HEAVY!r}}}))"
    probe = f"{code}\nimport json, sys\n{report}"
    # run outside the checkout: `python -c` puts the working directory first on sys.path, and
    # the checkout's packbot/ is the source tree, without the compiled extension
    out = subprocess.run(
        [sys.executable, "-c", probe],
        capture_output=True,
        text=True,
        check=True,
        cwd=tempfile.gettempdir(),
    ).stdout
    loaded: dict[str, bool] = json.loads(out.strip().splitlines()[-1])
    return loaded


def test_import_packbot_leaves_heavy_modules_unloaded() -> None:
    loaded = _loaded_after("import packbot")
    assert loaded == dict.fromkeys(HEAVY, False)


def test_public_names_still_import() -> None:
    loaded = _loaded_after(
        "import packbot\n"
        "from packbot import simulate, load_robot, SimResult, CollisionWorld, urdf_path\n"
        "assert all(hasattr(packbot, n) for n in packbot.__all__)"
    )
    assert not loaded["matplotlib"]


def test_plots_module_loads_matplotlib_on_demand() -> None:
    loaded = _loaded_after("import packbot.plots")
    assert loaded["matplotlib"]


def test_flagless_run_draws_nothing_and_loads_no_plotting(tmp_path: Path) -> None:
    code = (
        "from packbot.cli import main\n"
        f"rc = main(['run', 'collapse', '--out', {str(tmp_path)!r}])\n"
        "assert rc == 0, rc"
    )
    loaded = _loaded_after(code)
    assert not loaded["matplotlib"]
    assert not loaded["meshcat"]
    assert not loaded["scipy.optimize"]  # event location uses packbot.ode.brentq
    assert (tmp_path / "collapse.npz").is_file()
    assert not list(tmp_path.glob("*.png"))


def _recording(f: Callable[[float], float], seen: list[float]) -> Callable[[float], float]:
    def g(x: float) -> float:
        seen.append(x)
        return f(x)

    return g


def test_brentq_port_matches_scipy_iterate_for_iterate() -> None:
    rng = random.Random(7)
    checked = 0
    for _ in range(400):
        c = [rng.uniform(-3.0, 3.0) for _ in range(4)]

        def f(x: float, c: list[float] = c) -> float:
            return c[0] + c[1] * x + c[2] * math.sin(3.0 * x) + c[3] * x**3

        if f(-2.0) * f(2.0) >= 0.0:
            continue
        for xtol in (1e-12, 1e-6, 1e-2):
            seen_ours: list[float] = []
            seen_scipy: list[float] = []
            r1 = brentq(_recording(f, seen_ours), -2.0, 2.0, xtol=xtol)
            r2 = scipy_brentq(_recording(f, seen_scipy), -2.0, 2.0, xtol=xtol)
            assert r1 == r2
            assert seen_ours == seen_scipy
            checked += 1
    assert checked > 300


def test_brentq_rejects_bad_brackets_and_nan() -> None:
    with pytest.raises(ConfigurationError, match="opposite signs"):
        brentq(lambda x: x * x + 1.0, -1.0, 1.0)
    with pytest.raises(ConfigurationError, match="xtol"):
        brentq(lambda x: x, -1.0, 1.0, xtol=0.0)
    with pytest.raises(ConfigurationError, match="NaN"):
        brentq(lambda x: math.nan if x > 0.5 else x - 0.7, 0.0, 1.0)
    assert brentq(lambda x: x - 0.25, 0.0, 1.0) == pytest.approx(0.25, abs=1e-11)
