"""Type stub of the compiled extension (src/native/bindings.cpp)."""

from typing import Any

import numpy as np
from numpy.typing import NDArray

PINOCCHIO_VERSION: str
CONIC_STALL_OK: float

_F = NDArray[np.float64]

def lemke(M: _F, q: _F, max_iter: int, tol: float) -> tuple[_F, bool]: ...
def lcp_residual(M: _F, q: _F, z: _F) -> float: ...
def solve_conic(
    A: _F,
    g: _F,
    mus: _F,
    bound: _F,
    guess: _F,
    tol: float,
    max_iterations: int,
    rho0: float,
) -> tuple[_F, float, int, float]: ...
def conic_residual(A: _F, g: _F, x: _F, mus: _F, bound: _F) -> float: ...
def patch_material(
    p1: _F,
    p2: _F,
    n: _F,
    distance: float,
    N1: _F,
    o1: _F,
    Rg1: _F,
    tg1: _F,
    N2: _F,
    o2: _F,
    Rg2: _F,
    tg2: _F,
    RM1: _F,
    tM1: _F,
    RM2: _F,
    tM2: _F,
    patch_tol: float,
    check: bool,
) -> tuple[Any, ...]: ...

class ContactRhs:
    def __init__(
        self,
        types: list[str],
        parents: NDArray[np.int64],
        placements: NDArray[np.float64],
        axes: NDArray[np.float64],
        masses: NDArray[np.float64],
        levers: NDArray[np.float64],
        inertias: NDArray[np.float64],
        armature: NDArray[np.float64],
        gravity: NDArray[np.float64],
    ) -> None: ...
    @property
    def nv(self) -> int: ...
    def rows(self, q: _F, v: _F) -> tuple[_F, ...]: ...
    def evaluate(self, q: _F, v: _F, a_free: _F, minv: _F) -> tuple[Any, ...] | None: ...
    def forces(self, lam: _F, on1: NDArray[np.uint8]) -> tuple[Any, ...]: ...
    def set_layout(
        self,
        joints: NDArray[np.int64],
        masks: NDArray[np.float64],
        body: NDArray[np.int64],
        local: NDArray[np.float64],
        pair: NDArray[np.int64],
        rows: NDArray[np.int64],
        centre: NDArray[np.int64],
        normal_body: NDArray[np.int64],
        frame2: NDArray[np.float64],
        lim_joint: NDArray[np.int64],
        lim_side: NDArray[np.float64],
        lim_value: NDArray[np.float64],
    ) -> None: ...
    def set_patches(
        self,
        local: NDArray[np.float64],
        frame2: NDArray[np.float64],
        offset0: NDArray[np.float64],
        slide_tol2: NDArray[np.float64],
    ) -> None: ...
    def set_plan(
        self,
        engaged: NDArray[np.int64],
        row_slip: NDArray[np.int64],
        sticks: NDArray[np.int64],
        mu: float,
        stick_speed: float,
        baumgarte: float,
    ) -> None: ...
    def set_slip_dirs(self, slip_dir: NDArray[np.float64]) -> None: ...
    def accel(
        self,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        x: NDArray[np.float64],
        from_tau: bool,
        out: NDArray[np.float64],
    ) -> bool: ...
    def set_torque(
        self,
        applied: NDArray[np.float64],
        viscous: NDArray[np.float64],
        coulomb_dir: NDArray[np.float64],
    ) -> None: ...
    def first(self, Z: NDArray[np.float64]) -> bool: ...
    def dopri(
        self,
        h: float,
        Z: NDArray[np.float64],
        ay0: NDArray[np.float64],
        atol: NDArray[np.float64],
        rtol: float,
        y1: NDArray[np.float64],
        ay1: NDArray[np.float64],
    ) -> float: ...
    def stiffness(self) -> float: ...
    def rosenbrock(
        self,
        h: float,
        Z: NDArray[np.float64],
        ay0: NDArray[np.float64],
        atol: NDArray[np.float64],
        rtol: float,
        y1: NDArray[np.float64],
        ay1: NDArray[np.float64],
    ) -> float: ...
    def jac_radius(self) -> float: ...
    def set_conditions(
        self,
        offset0: NDArray[np.float64],
        slide_tol2: NDArray[np.float64],
        force_band: float,
        point_tol: float,
        stick_band: float,
    ) -> None: ...
    def end_eval(self, y1: NDArray[np.float64]) -> tuple[Any, ...] | None: ...
    def eval_at(self, y: NDArray[np.float64]) -> tuple[Any, ...] | None: ...
    def row_condition_at(self, y: NDArray[np.float64], r: int) -> float: ...
    def set_locks(self, locked: NDArray[np.int64]) -> None: ...
    def set_screen(
        self, rows: NDArray[np.float64], torque_band: float, accel_band: float
    ) -> None: ...
    def end_screen(self, y1: NDArray[np.float64], margin: float) -> float: ...
    def energies(
        self, Q: NDArray[np.float64], V: NDArray[np.float64], out: NDArray[np.float64]
    ) -> None: ...
    def neutral_velocity(
        self, q0: NDArray[np.float64], q1: NDArray[np.float64], v: NDArray[np.float64]
    ) -> float: ...
    def lock_torques_at(self, q: _F, v: _F, tau: _F) -> _F | None: ...
    def end_locks(
        self, y1: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None: ...
    def window_step(
        self,
        y: NDArray[np.float64],
        h: float,
        swept: NDArray[np.int64],
        dist: NDArray[np.float64],
        sweep_margin: float,
        reach: NDArray[np.float64],
        active_gap: float,
        upper: NDArray[np.float64],
        lower: NDArray[np.float64],
        limit_gap: float,
        mu: float,
        restitution: float,
        zeno: float,
        touch_gap: float,
        boxes: NDArray[np.int64],
        bound: NDArray[np.float64],
        guess: NDArray[np.float64],
        rho0: float,
        tol: float,
        max_iterations: int,
        ok: float,
        out_vf: NDArray[np.float64],
        out_v1: NDArray[np.float64],
        out_q1: NDArray[np.float64],
        checked: bool = True,
    ) -> tuple[Any, ...]: ...
    def row_root(
        self,
        Z: NDArray[np.float64],
        t0: float,
        t1: float,
        h: float,
        y1: NDArray[np.float64],
        hermite: bool,
        r: int,
        g0: float,
        g1: float,
        xtol: float,
    ) -> float: ...
    def window_run(
        self,
        api: Any,
        y: NDArray[np.float64],
        t: float,
        t_end: float,
        t_commit: float,
        h_window: float,
        until: float,
        quiet: int,
        quiet_steps: int,
        last_valid: bool,
        last_sig: NDArray[np.int64],
        swept: NDArray[np.int64],
        dist: NDArray[np.float64],
        sweep_margin: float,
        best: int,
        best_d: float,
        reach: NDArray[np.float64],
        active_gap: float,
        upper: NDArray[np.float64],
        lower: NDArray[np.float64],
        limit_gap: float,
        mu: float,
        restitution: float,
        zeno: float,
        touch_gap: float,
        boxes: NDArray[np.int64],
        coul: NDArray[np.float64],
        guess: NDArray[np.float64],
        rho0: float,
        tol: float,
        max_iterations: int,
        ok: float,
        applied: NDArray[np.float64],
        has_e: bool,
        e_last: float,
        step_angle: float,
        sweep_slack: float,
        project_depth: float,
        impulse_band: float,
        min_d: float,
        max_steps: int,
    ) -> dict[str, Any]: ...
    def project_round(
        self,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        minv: NDArray[np.float64],
        touch_gap: float,
        pen_tol: float,
        res_tol: float,
        out_q: NDArray[np.float64],
    ) -> int: ...
    def impact(
        self,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        minv: NDArray[np.float64],
        mu: float,
        restitution: float,
        zeno: float,
        touch_gap: float,
        res_tol: float,
        conic_tol: float,
        max_iterations: int,
        accept: float,
        out_v: NDArray[np.float64],
    ) -> tuple[int, bool]: ...
    def stop_slow(
        self,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        minv: NDArray[np.float64],
        touch_gap: float,
        speed_band: float,
        stick_speed: float,
        capture_speed: float,
        residual_tol: float,
        dependent_row: float,
        out_v: NDArray[np.float64],
    ) -> int: ...
    def select_modes(
        self,
        q: NDArray[np.float64],
        v: NDArray[np.float64],
        a_free: NDArray[np.float64],
        minv: NDArray[np.float64],
        keep: bool,
        held: NDArray[np.int64],
        stick_io: NDArray[np.uint8],
        slip_io: NDArray[np.float64],
        mu: float,
        touch_gap: float,
        speed_band: float,
        stick_speed: float,
        force_band: float,
        stick_band: float,
        baumgarte: float,
        residual_tol: float,
    ) -> tuple[int, bool, Any, Any, int, bool]: ...
    def last(self) -> tuple[NDArray[np.float64], ...]: ...
    def minv_at(self, q: NDArray[np.float64], out: NDArray[np.float64]) -> None: ...
    def free_accel_at(
        self, q: NDArray[np.float64], v: NDArray[np.float64], out: NDArray[np.float64]
    ) -> None: ...
    def set_reach(self, reach: NDArray[np.float64], margin: float, max_step: float) -> None: ...
    def step_bound(self, y: NDArray[np.float64]) -> float: ...

class Stretch:
    def __init__(
        self,
        rhs: ContactRhs,
        api: Any,
        margin: float,
        atol: NDArray[np.float64],
        rtol: float,
        h_min: float,
        near: float,
        pen_tol: float,
        crawl_steps: int,
        crawl_step: float,
        sample_dt: float,
        duration: float,
        stiff_switch: bool,
    ) -> None: ...
    def run(
        self,
        f_pending: bool,
        Z: NDArray[np.float64],
        ay: NDArray[np.float64],
        t: float,
        h: float,
        max_factor: float,
        stiff_run: int,
        stiff: bool,
        next_sample: int,
        min_d: float,
        t_end: float,
        t_last: float,
        t_sched: float,
        active: NDArray[np.int64],
        limits: NDArray[np.int64],
        lim_value: NDArray[np.float64],
        crawl: NDArray[np.float64],
        y_pend: NDArray[np.float64],
        ay_pend: NDArray[np.float64],
    ) -> dict[str, Any]: ...
    def set_repatch(
        self,
        tol: float,
        patch_tol: float,
        face_align: float,
        slide_tol2: float,
        touch_gap: float,
        res_tol: float,
        mu: float,
        speed_band: float,
        stick_speed: float,
        force_band: float,
        stick_band: float,
        baumgarte: float,
        mode_res_tol: float,
        hand_back_at: int = 0,
    ) -> None: ...
    def set_modes(
        self,
        on: bool,
        stick: NDArray[np.uint8],
        on1: NDArray[np.uint8],
        slip: NDArray[np.float64],
        engaged: NDArray[np.int64],
    ) -> None: ...
    def repatched(self) -> dict[str, Any]: ...
