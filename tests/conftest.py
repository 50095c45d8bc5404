from collections.abc import Iterator

import numpy as np
import pytest

import packbot
from packbot.contact import stretch


@pytest.fixture(scope="session")
def robot() -> packbot.Robot:
    return packbot.load_robot()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20100811)


@pytest.fixture(scope="module")
def step_by_step() -> Iterator[None]:
    """The contact-normal mode's steps one by one (its compiled stretch switched off).

    For the tests of the per-step machinery (the native attempts, the step end's screen, the
    stiff switch, the kept distances), which watch the steps the loop takes in Python; the
    stretch takes them with the same arithmetic (tests/test_stretch.py). A module that uses
    it does so with an autouse fixture of its own, instantiated before its other
    module-scoped fixtures (which may run collapses).
    """
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(stretch, "ENABLED", False)
        yield
