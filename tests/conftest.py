import numpy as np
import pytest

import packbot


@pytest.fixture(scope="session")
def robot() -> packbot.Robot:
    return packbot.load_robot()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20100811)
