from collections.abc import Iterator

import numpy as np
import pytest

import packbot
from packbot.contact.normal_law import NormalLaw


@pytest.fixture(scope="session")
def robot() -> packbot.Robot:
    return packbot.load_robot()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20100811)


@pytest.fixture(scope="module")
def step_by_step() -> Iterator[None]:
    """The contact-normal mode's steps one by one: no compiled stretch is offered.

    Each step then comes to the loop as a step the stretch hands back does (the native step,
    the step end's screen, the stiff switch, the kept distances in Python), for the tests of
    that per-step machinery; an arm captured at rest is still held there. A module that uses
    it does so with an autouse fixture of its own, instantiated before its other
    module-scoped fixtures (which may run collapses).
    """

    def no_stretch(self, stepper, t_end, *args):
        return self._hold_at_rest(stepper, t_end) if self.normal.resting else None

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(NormalLaw, "stretch", no_stretch)
        yield


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """A test that draws a page in headless Chromium (the ``chromium`` fixture) is
    ``nonnumeric``: what it checks is the page, not the numbers under it."""
    for item in items:
        if "chromium" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.nonnumeric)
