"""Type stub of the compiled collision sweep (src/native/sweep.cpp)."""

from typing import Any

import numpy as np
from numpy.typing import NDArray

COAL_VERSION: str
PINOCCHIO_VERSION: str

class Sweep:
    def __init__(
        self,
        types: list[str],
        parents: NDArray[np.int64],
        joint_placements: NDArray[np.float64],
        axes: NDArray[np.float64],
        kinds: NDArray[np.int64],
        joints: NDArray[np.int64],
        placements: NDArray[np.float64],
        params: NDArray[np.float64],
        points: NDArray[np.float64],
        point_start: NDArray[np.int64],
        triangles: NDArray[np.int64],
        triangle_start: NDArray[np.int64],
        box_half: NDArray[np.float64],
        box_centre: NDArray[np.float64],
        first: NDArray[np.int64],
        second: NDArray[np.int64],
        gjk_tolerance: float,
        epa_tolerance: float,
        gjk_max_iterations: int,
        epa_max_iterations: int,
        absolute_criterion: bool,
        cached_guess: bool,
    ) -> None: ...
    def sweep(
        self, q: NDArray[np.float64], margin: float
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], int, float]: ...
    def candidates(self, q: NDArray[np.float64], margin: float) -> NDArray[np.int64]: ...
    def distances(
        self, q: NDArray[np.float64], pairs: NDArray[np.int64]
    ) -> tuple[
        NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]
    ]: ...
    def witness(
        self, p1: NDArray[np.float64], p2: NDArray[np.float64], normal: NDArray[np.float64]
    ) -> None: ...
    def boxes(self, lo: NDArray[np.float64], hi: NDArray[np.float64]) -> None: ...
    def last_q(self) -> NDArray[np.float64]: ...
    def fresh(self) -> Sweep: ...
    def api(self) -> Any: ...
    def patches(
        self, q: NDArray[np.float64], pairs: NDArray[np.int64], tol: float
    ) -> tuple[
        NDArray[np.int64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
    ]: ...
    def point_distance(
        self, q: NDArray[np.float64], k: int
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
    def set_planes(
        self, N: NDArray[np.float64], o: NDArray[np.float64], start: NDArray[np.int64]
    ) -> None: ...
    @property
    def has_planes(self) -> bool: ...
    def materials(
        self,
        q: NDArray[np.float64],
        pairs: NDArray[np.int64],
        tol: float,
        patch_tol: float,
        face_align: float,
    ) -> tuple[NDArray[Any], ...]: ...
    @property
    def n_pairs(self) -> int: ...
