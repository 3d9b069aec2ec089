"""Peer comparison: Betts' minimum-time reorientation and a finite-burn fuel orbit raise, written the
way a user of Dymos (OpenMDAO's optimal-control library) would write them.

Dymos and OpenMDAO are an optional extra (``pip install -e .[peer-dymos]``), never needed at run time.

**Optimizer.**  Dymos reaches IPOPT only through pyOptSparse (``om.pyOptSparseDriver``), which is not on
the Python package index (conda-forge or a source build only); the modOpt driver's library is not on
the index either (the ``modopt`` there is an unrelated project).  So the peer runs what a pip user has:
``om.ScipyOptimizeDriver(optimizer='SLSQP')`` with ``declare_coloring()`` (total-derivative colouring),
``tol`` 1e-9, ``maxiter`` 2000.  Where pyoptsparse is installed, ``_driver`` is the one place to change
(``om.pyOptSparseDriver(optimizer='IPOPT')``); that path is not measured here.

**Transcription.**  ``dm.Radau(num_segments=N // 3, order=3, compressed=True)``: 3 LGR collocation points
per segment, N + 1 state nodes, the same number as our N steps; N must be a multiple of 3.  The ODE
components take their partials by complex step with ``declare_coloring(wrt='*', method='cs')``, as the
Dymos documentation offers for models without hand-written derivatives.

**Betts' reorientation** (configs/slew_time_optimal.yaml, ``slew``; the symmetric variant ``slew_sym``):
states the unit quaternion q (scalar first, body -> inertial, 4 states, not normalized by the
transcription) and the body rates w (3), control the body torque tau (3) with the box as control bounds,
free final time in the file's bounds, objective ``time``.  Boundary conditions: q(0) = (1, 0, 0, 0),
w(0) = w(T) = 0 (``fix_initial``/``fix_final``), and the *vector part* of q(T) equal to the target's
(``add_boundary_constraint(..., indices=[1, 2, 3])``): fixing all four components would put four
constraints on a three-dimensional set.  The torque is bang-bang, so the control has neither value nor
rate continuity across segments (``continuity=False, rate_continuity=False``, as in Dymos' own
flying-robot minimum-time example).  Start: our first start (the screw interpolation with the seed-0
symmetry-breaking torques, ``perturbed``) interpolated onto the peer's nodes, and the
file's T guess.

**Fuel orbit raise** (configs/orbit_raise_fuel.yaml, ``orbit_raise``): the file's body is a rigid body
(m = 1, J = diag(0.02, 0.03, 0.04)) under point-mass gravity in normalized units (mu = 4 pi^2), whose
gravity-gradient (MacCullagh) terms change the force by ~10 %, and whose target fixes the attitude's z
axis along the orbit normal and the body at rest; so the peer writes the same model, not a point mass:
states position r, velocity v (inertial), q, w and the fuel integral J; controls the thrust magnitude
s_f in [0, 40] with a direction d_f (3) and the torque magnitude s_m in [0, 1] with a direction d_m (3),
path constraints |d_f|^2 <= 1 and |d_m|^2 <= 1, dJ/dt = w_f s_f + w_m s_m, objective J(T) (the
magnitude-direction form of the L1 cost, as ours).  The force and moment are MacCullagh's (written out in
the ODE).  Terminal conditions: |r| = 1.3, e_n^T r = 0, the body z axis along +-e_n (two rows), v the
circular velocity at r, w = 0 -- the rows of our orbit target.  Start: our rollout (free motion) at the
nodes, zero thrust.

**Re-flight.**  The peer's controls are flown by scipy's DOP853 (rtol = atol = 1e-12) on the equations
(1)-(4) of docs/mathematics.md with R as nine entries and the force and moment of *our* model (by its
AD; an independent check of the peer's hand-written gravity), segment by segment with the controls as
the Radau transcription defines them: in each segment the Lagrange polynomial through its 4 control
nodes (for the orbit raise the product s(t) d(t) of the interpolants, as the ODE sees them).  Ours are
flown the same way, the LGVI's node controls linear between nodes (first order: piecewise constant).
Both terminal errors are the measure of docs/mathematics.md §8 on the re-flown state.

    .venv/bin/python scripts/peer_dymos.py slew 60
    .venv/bin/python scripts/peer_dymos.py --compare slew --N 60,120 --runs 3

``--compare`` runs ours (``se3ocp.solve``, default settings) and the peer at equal N, each in fresh
processes, round-robin, medians of ``--runs``; ratios only when both converged.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

ORDER = 3            # Radau collocation points per segment
MAX_ITER = 2000      # SLSQP's major iterations

#: case -> bundled maneuver file
STEMS = {"slew": "slew_time_optimal", "slew_sym": "slew_time_optimal_symmetric", "orbit_raise": "orbit_raise_fuel"}
#: the readable parts of the re-flown terminal error (see _miss)
MISSES = ("attitude_miss_deg", "rate_miss", "radius_miss", "speed_miss")
#: published optima (T* of Betts 2010 sect. 6.8; Bilimoria & Wie 1993)
PUBLISHED = {"slew": 28.6304077, "slew_sym": 3.2431}


# ----------------------------------------------------------------------------- quaternion algebra (complex-step safe)
def quat_to_R(q):
    """Rotation matrices (..., 3, 3), body -> inertial, of quaternions q (..., 4), scalar first, not
    necessarily unit (the transcription does not keep |q| = 1): R of q / |q|."""
    a, b, c, d = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    n2 = a * a + b * b + c * c + d * d
    R = np.stack([np.stack([a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)], -1),
                  np.stack([2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)], -1),
                  np.stack([2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d], -1)], -2)
    return R / n2[..., None, None]


def quat_rate(q, w):
    """dq/dt = (1/2) q (x) (0, w), w the body rates: (nn, 4)."""
    a, b, c, d = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    return 0.5 * np.stack([-b * x - c * y - d * z, a * x + c * z - d * y, a * y - b * z + d * x, a * z + b * y - c * x], -1)


def R_to_quat(R):
    """A unit quaternion (scalar first, a >= 0) of one rotation matrix (Shepperd's method)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    q = np.array([w, x, y, z])
    return q if q[0] >= 0 else -q


def _cross(a, b):
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], -1)


# ----------------------------------------------------------------------------- the peer's ODEs (OpenMDAO components)
try:
    import openmdao.api as om
    _Component = om.ExplicitComponent
except ImportError:      # the peer is optional: ours runs without it
    om = None
    _Component = object


class SlewODE(_Component):
    """Euler's equations and quaternion kinematics of a torqued rigid body without gravity, at nn nodes:
    dq/dt = (1/2) q (x) (0, w), dw/dt = J^-1 (tau - w x J w), w and tau in the body frame."""

    def initialize(self):
        self.options.declare("num_nodes", types=int)
        self.options.declare("inertia", types=np.ndarray)

    def setup(self):
        nn = self.options["num_nodes"]
        self.add_input("q", shape=(nn, 4))
        self.add_input("w", shape=(nn, 3), units="rad/s")
        self.add_input("tau", shape=(nn, 3), units="N*m")
        self.add_output("q_dot", shape=(nn, 4), units="1/s")
        self.add_output("w_dot", shape=(nn, 3), units="rad/s**2")
        self.declare_coloring(wrt="*", method="cs")

    def compute(self, inputs, outputs):
        J = self.options["inertia"]
        w = inputs["w"]
        outputs["q_dot"] = quat_rate(inputs["q"], w)
        outputs["w_dot"] = (inputs["tau"] - _cross(w, w @ J.T)) @ np.linalg.inv(J).T


class OrbitRaiseODE(_Component):
    """A rigid body (mass m, inertia J) under a point mass mu at the origin with MacCullagh's
    second-order potential U = -mu m/r - mu/(2 r^3) (tr J - 3 rhat^T R J R^T rhat), thrust s_f d_f
    (inertial) and torque s_m d_m (body), at nn nodes:

        dr/dt = v,  dv/dt = (f + s_f d_f)/m,  dq/dt = (1/2) q (x) (0, w),
        dw/dt = J^-1 (M + s_m d_m - w x J w),  dJ/dt = w_f s_f + w_m s_m,

    f = -dU/dr, M = 3 mu/r^3 r_b x J r_b (r_b = R^T rhat); also |d_f|^2, |d_m|^2 (path constraints) and
    the orbit-target rows (|r| - r_d, e_n^T r, a^T R b, a'^T R b, v - sqrt(mu/r_d) e_n x r/r_d)."""

    def initialize(self):
        for name, kind in (("num_nodes", int), ("mass", float), ("inertia", np.ndarray), ("mu", float),
                           ("radius", float), ("basis", tuple), ("body_axis", np.ndarray), ("weights", tuple)):
            self.options.declare(name, types=kind)

    def setup(self):
        nn = self.options["num_nodes"]
        for name, n in (("r", 3), ("v", 3), ("q", 4), ("w", 3), ("s_f", 1), ("d_f", 3), ("s_m", 1), ("d_m", 3)):
            self.add_input(name, shape=(nn, n) if n > 1 else (nn,))
        for name, n in (("r_dot", 3), ("v_dot", 3), ("q_dot", 4), ("w_dot", 3), ("J_dot", 1), ("d_f_sq", 1),
                        ("d_m_sq", 1), ("radius_err", 1), ("plane_err", 1), ("axis_err", 2), ("v_err", 3)):
            self.add_output(name, shape=(nn, n) if n > 1 else (nn,))
        self.declare_coloring(wrt="*", method="cs")

    def compute(self, inputs, outputs):
        o = self.options
        m, J, mu, rd = o["mass"], o["inertia"], o["mu"], o["radius"]
        n, a, a2 = o["basis"]
        r, v, q, w = inputs["r"], inputs["v"], inputs["q"], inputs["w"]
        R = quat_to_R(q)
        rn = np.sqrt(np.sum(r * r, axis=1))
        rin = np.einsum("kij,jl,kml->kim", R, J, R)                    # R J R^T (inertial)
        Jr = np.einsum("kij,kj->ki", rin, r)
        rJr = np.sum(r * Jr, axis=1)
        f = -(mu * m / rn**3 + 1.5 * mu * np.trace(J) / rn**5 - 7.5 * mu * rJr / rn**7)[:, None] * r \
            - (3 * mu / rn**5)[:, None] * Jr
        rb = np.einsum("kji,kj->ki", R, r) / rn[:, None]               # R^T rhat (body)
        M = (3 * mu / rn**3)[:, None] * _cross(rb, rb @ J.T)
        outputs["r_dot"] = v
        outputs["v_dot"] = (f + inputs["s_f"][:, None] * inputs["d_f"]) / m
        outputs["q_dot"] = quat_rate(q, w)
        outputs["w_dot"] = (M + inputs["s_m"][:, None] * inputs["d_m"] - _cross(w, w @ J.T)) @ np.linalg.inv(J).T
        wf, wm = o["weights"]
        outputs["J_dot"] = wf * inputs["s_f"] + wm * inputs["s_m"]
        outputs["d_f_sq"] = np.sum(inputs["d_f"] ** 2, axis=1)
        outputs["d_m_sq"] = np.sum(inputs["d_m"] ** 2, axis=1)
        axis = np.einsum("kij,j->ki", R, o["body_axis"])
        outputs["radius_err"] = rn - rd
        outputs["plane_err"] = r @ n
        outputs["axis_err"] = np.stack([axis @ a, axis @ a2], -1)
        outputs["v_err"] = v - np.sqrt(mu / rd) / rd * _cross(np.broadcast_to(n, r.shape), r)


# ----------------------------------------------------------------------------- the peer's problems
def _problem(case: str, N: int, scheme: str | None = None):
    """Our Problem of the case's maneuver file at N steps (``scheme`` overrides the discretization)."""
    import se3ocp

    sets = [f"horizon.N={N}"] + ([f"discretization={scheme}"] if scheme else [])
    return se3ocp.load(ROOT / "configs" / f"{STEMS[case]}.yaml", sets).problem


def _driver():
    """The OpenMDAO driver: SLSQP through scipy (what pip installs; the default), or with
    PEER_OPTIMIZER=ipopt IPOPT through OpenMDAO's modOpt driver (modOpt installed from its source), with
    total-derivative colouring either way."""
    import os

    if os.environ.get("PEER_OPTIMIZER", "slsqp") == "ipopt":
        d = om.modOptDriver(optimizer="IPOPT", maxiter=MAX_ITER, disp=False, turn_off_outputs=True)
        # the settings Dymos' own examples give IPOPT
        d.opt_settings.update({"tol": 1e-9, "print_level": int(os.environ.get("PEER_PRINT", "0")),
                               "mu_init": 1e-3, "mu_strategy": "monotone", "nlp_scaling_method": "gradient-based",
                               "alpha_for_y": "safer-min-dual-infeas", "bound_mult_init_method": "mu-based"})
    else:
        d = om.ScipyOptimizeDriver(optimizer="SLSQP", maxiter=MAX_ITER, disp=False)   # OpenMDAO's tol, 1e-6
    d.declare_coloring()
    return d


def _phase(ode_class, N: int, ode_kwargs: dict):
    import dymos as dm

    if N % ORDER:
        raise SystemExit(f"peer_dymos.py: N = {N}: expected a multiple of {ORDER} (Radau segments of order {ORDER})")
    tx = dm.Radau(num_segments=N // ORDER, order=ORDER, compressed=True)
    return dm.Phase(ode_class=ode_class, transcription=tx, ode_init_kwargs=ode_kwargs)


def slew_guess(prob, N: int, kick: float = 0.2, seed: int = 0) -> dict:
    """The eigenaxis maneuver (rest to rest about the axis of R_0^T R_d, bang-bang angular acceleration
    at the largest rate the torque box allows, the torque from the inverse dynamics J a theta'' +
    w x J w), with seeded normal torques of ``kick`` times the bound added to break its symmetry (it is
    a stationary point of the time objective), at N + 1 equally spaced times over its duration."""
    from se3ocp.transcription.geometry.state import unpack_states
    from se3ocp.transcription.geometry.so3 import log_so3

    J, b = prob.model.inertia, prob.control.moment_bound.b
    R0, Rd = unpack_states(prob.X0).R[0], unpack_states(prob.Xd).R[0]
    e = np.asarray(log_so3(R0.T @ Rd), float).ravel()
    th, a = float(np.linalg.norm(e)), e / np.linalg.norm(e)
    acc = float(np.min(b / np.maximum(np.abs(J @ a), 1e-300)))
    T = 2 * np.sqrt(th / acc)
    t = np.linspace(0.0, T, N + 1)
    first = t <= T / 2
    ang = np.where(first, 0.5 * acc * t**2, th - 0.5 * acc * (T - t) ** 2)
    rate = np.where(first, acc * t, acc * (T - t))
    w = rate[:, None] * a
    q0 = R_to_quat(R0)
    dq = np.hstack([np.cos(ang / 2)[:, None], np.sin(ang / 2)[:, None] * a])     # body-frame rotation
    q = np.array([[q0[0] * d[0] - q0[1:] @ d[1:], *(q0[0] * d[1:] + d[0] * q0[1:] + np.cross(q0[1:], d[1:]))]
                  for d in dq])
    tau = np.where(first, acc, -acc)[:, None] * (J @ a) + np.cross(w, w @ J.T)
    tau += kick * b * np.random.default_rng(seed).standard_normal(tau.shape)
    return {"T": T, "t": t, "q": q, "w": w, "t_u": t, "tau": np.clip(tau, -b, b)}


def build_slew(prob, N: int, guess: dict):
    """The Dymos model of a time-optimal slew (see the module docstring) with ``guess`` set; returns
    (problem, phase).  The target quaternion is the guess's last one (its sign picks the branch)."""
    import dymos as dm

    J, b = prob.model.inertia, prob.control.moment_bound.b
    if np.ptp(b) > 0:    # Dymos takes one bound for every component (or a value per node and component)
        raise SystemExit("peer_dymos.py: the slew peer is written for one torque bound on every axis")
    b = float(b[0])
    lo, hi = prob.time_bounds
    p = om.Problem(model=om.Group(), reports=False)
    p.driver = _driver()
    traj = p.model.add_subsystem("traj", dm.Trajectory())
    phase = traj.add_phase("phase0", _phase(SlewODE, N, {"inertia": np.asarray(J, float)}))
    phase.set_time_options(fix_initial=True, duration_bounds=(lo, hi), duration_ref=guess["T"], units="s")
    w_ref = float(np.abs(guess["w"]).max())                   # the eigenaxis maneuver's peak rate
    phase.add_state("q", shape=(4,), rate_source="q_dot", targets="q", fix_initial=True)
    phase.add_state("w", shape=(3,), rate_source="w_dot", targets="w", units="rad/s", ref=w_ref,
                    fix_initial=True, fix_final=True)
    phase.add_control("tau", shape=(3,), targets="tau", units="N*m", lower=-b, upper=b, ref=b,
                      continuity=False, rate_continuity=False)
    phase.add_boundary_constraint("q", loc="final", indices=[1, 2, 3], equals=guess["q"][-1, 1:])
    phase.add_objective("time", loc="final", ref=guess["T"])
    p.model.linear_solver = om.DirectSolver()
    p.setup()
    phase.set_time_val(initial=0.0, duration=guess["T"])
    phase.set_state_val("q", guess["q"], time_vals=guess["t"])
    phase.set_state_val("w", guess["w"], time_vals=guess["t"])
    phase.set_control_val("tau", guess["tau"], time_vals=guess["t_u"])
    return p, phase


def orbit_raise_guess(prob, N: int) -> dict:
    """Our first start of the fuel objective, the rollout (free motion of our scheme), at the N + 1
    nodes; thrust and torque off (magnitudes 0, directions e_1)."""
    from se3ocp.transcription.strategy.starts import rollout
    from se3ocp.transcription.geometry.state import unpack_states

    g = rollout(prob.replace(N=N))
    s = unpack_states(g.X)
    q = np.array([R_to_quat(R) for R in s.R])
    for k in range(1, N + 1):
        if q[k] @ q[k - 1] < 0:
            q[k] = -q[k]
    return {"t": np.linspace(0.0, prob.T, N + 1), "r": s.x, "v": s.gamma / prob.model.mass, "q": q,
            "w": s.Pi @ np.linalg.inv(prob.model.inertia).T}


def build_orbit_raise(prob, N: int, guess: dict):
    """The Dymos model of the fuel orbit raise (see the module docstring) with ``guess`` set; returns
    (problem, phase)."""
    import dymos as dm

    c, model, target = prob.control, prob.model, prob.terminal
    if not all(b is not None and np.isfinite(b.radius) for b in (c.force_bound, c.moment_bound)):
        raise SystemExit("peer_dymos.py: the orbit-raise peer is written for norm bounds on thrust and torque")
    wf, wm = float(c.W[0, 0]), float(c.W[3, 3])
    n, a, a2 = target.plane_basis()
    kw = {"mass": float(model.mass), "inertia": np.asarray(model.inertia, float), "mu": float(model.mu),
          "radius": float(target.radius), "basis": (n, a, a2), "body_axis": target.body_axis, "weights": (wf, wm)}
    p = om.Problem(model=om.Group(), reports=False)
    p.driver = _driver()
    traj = p.model.add_subsystem("traj", dm.Trajectory())
    phase = traj.add_phase("phase0", _phase(OrbitRaiseODE, N, kw))
    phase.set_time_options(fix_initial=True, fix_duration=True)
    rd, vd = float(target.radius), float(np.sqrt(model.mu / target.radius))
    w_ref = float(c.moment_bound.b / np.min(np.diag(model.inertia)) * prob.T / 4)
    for name, n_, ref, final in (("r", 3, rd, False), ("v", 3, vd, False), ("q", 4, 1.0, False),
                                 ("w", 3, w_ref, True)):
        phase.add_state(name, shape=(n_,), rate_source=f"{name}_dot", targets=name, ref=ref, fix_initial=True,
                        fix_final=final)
    fuel_ref = float(wf * c.force_bound.b + wm * c.moment_bound.b) * prob.T / 10
    phase.add_state("J", rate_source="J_dot", fix_initial=True, ref=fuel_ref)
    for mag, d, b in (("s_f", "d_f", c.force_bound.b), ("s_m", "d_m", c.moment_bound.b)):
        phase.add_control(mag, targets=mag, lower=0.0, upper=float(b), ref=float(b), continuity=False,
                          rate_continuity=False)
        phase.add_control(d, shape=(3,), targets=d, lower=-1.0, upper=1.0, continuity=False, rate_continuity=False)
        phase.add_path_constraint(f"{d}_sq", upper=1.0)
    phase.add_boundary_constraint("radius_err", loc="final", equals=0.0, ref=rd)
    phase.add_boundary_constraint("plane_err", loc="final", equals=0.0, ref=rd)
    phase.add_boundary_constraint("axis_err", loc="final", equals=0.0)
    phase.add_boundary_constraint("v_err", loc="final", equals=0.0, ref=vd)
    phase.add_objective("J", loc="final", ref=fuel_ref)
    p.model.linear_solver = om.DirectSolver()
    p.setup()
    phase.set_time_val(initial=0.0, duration=prob.T)
    for name in ("r", "v", "q", "w"):
        phase.set_state_val(name, guess[name], time_vals=guess["t"])
    phase.set_state_val("J", [0.0, 0.0])
    for name, val in (("s_f", 0.0), ("s_m", 0.0), ("d_f", [1.0, 0.0, 0.0]), ("d_m", [1.0, 0.0, 0.0])):
        phase.set_control_val(name, np.tile(val, (2, 1)) if np.ndim(val) else [val, val])
    return p, phase


# ----------------------------------------------------------------------------- re-flight (scipy DOP853)
def refly(model, X0: np.ndarray, control, breaks: np.ndarray, rtol: float = 1e-12, atol: float = 1e-12) -> np.ndarray:
    """Fly (1)-(4) of docs/mathematics.md (R as nine entries, the force and moment of ``model``) from X0
    (18) under ``control(t) -> u (6)`` with DOP853, restarted at each of ``breaks`` (where the control may
    have a kink or a jump); returns the state (18) at breaks[-1]."""
    from scipy.integrate import solve_ivp

    from peer_rockit import _rhs_functions

    rhs = _rhs_functions(model)
    X = np.asarray(X0, float)
    for t0, t1 in zip(breaks[:-1], breaks[1:]):
        sol = solve_ivp(lambda t, y: np.asarray(rhs(y, control(t))).ravel(), (t0, t1), X, method="DOP853",
                        rtol=rtol, atol=atol)
        if not sol.success:
            return np.full(18, np.nan)
        X = sol.y[:, -1]
    return X


def hold(times: np.ndarray, U: np.ndarray):
    """Our controls U (6, n) at ``times`` (Solution.control_times) as the scheme defines them between
    the nodes: the LGVI's node controls u_0..u_N at t_0..t_N linear in between (first-order hold); the
    first-order scheme's u_1..u_N at t_1..t_N, u_k+1 constant on [t_k, t_k+1).  Returns (control(t) ->
    (6,), breaks)."""
    if times[0] == 0.0:
        return (lambda s: np.array([np.interp(s, times, u) for u in U])), times
    breaks = np.concatenate([[0.0], times])
    return (lambda s: U[:, min(int(np.searchsorted(breaks, s, side="right")) - 1, U.shape[1] - 1)]), breaks


def radau_controls(phase, time: np.ndarray, values: dict):
    """The peer's controls as the Radau transcription defines them: in each segment the Lagrange
    polynomial through the control values at its LGR nodes (``values``: name -> (all nodes, ...)).
    Returns (name -> function of t, segment break times)."""
    from scipy.interpolate import BarycentricInterpolator

    gd = phase.options["transcription"].grid_data
    col = set(gd.subset_node_indices["col"].tolist())
    segs = []
    for i0, i1 in gd.segment_indices:
        idx = [i for i in range(i0, i1) if i in col]
        segs.append((time[i0], time[i1 - 1], {k: BarycentricInterpolator(time[idx], v[idx]) for k, v in values.items()}))
    breaks = np.array([s[0] for s in segs] + [segs[-1][1]])

    def at(name):
        def f(t):
            k = min(max(int(np.searchsorted(breaks, t, side="right")) - 1, 0), len(segs) - 1)
            return np.atleast_1d(segs[k][2][name](t)).ravel()
        return f
    return {k: at(k) for k in values}, breaks


# ----------------------------------------------------------------------------- solving and measuring
def _bound_violation(prob, control, T: float) -> float:
    """The largest excess of the control over its bounds on a fine grid (16 points per node interval):
    collocation bounds the control at the nodes only."""
    ts = np.linspace(0.0, T, 16 * prob.N + 1)
    U = np.array([control(t) for t in ts]).T
    worst = 0.0
    for sl, bound in ((slice(0, 3), prob.control.force_bound), (slice(3, 6), prob.control.moment_bound)):
        if bound is not None and not bound.removed:
            worst = max(worst, float(-bound.margin(U[sl].T).min()))
    return max(worst, 0.0)


def _reflown(rec: dict, prob, control, breaks: np.ndarray, T: float) -> dict:
    """``rec`` with the terminal error (docs/mathematics.md §8) of the DOP853 re-flight of ``control``
    over [0, T] and the bound violation between the nodes."""
    from se3ocp.transcription.ocp import terminal_error

    XN = refly(prob.model, prob.X0, control, breaks)
    rec["terminal_error"] = terminal_error(XN, prob) if np.all(np.isfinite(XN)) else float("inf")
    rec.update(_miss(XN, prob))
    rec["bound_violation"] = _bound_violation(prob, control, T)
    return rec


def _miss(XN: np.ndarray, prob) -> dict:
    """The re-flown terminal error in readable units: for a state target the attitude miss (deg) and the
    body-rate miss (rad/s); for an orbit target the radius miss and the speed miss (normalized units)."""
    from se3ocp.transcription.geometry.state import unpack_states
    from se3ocp.transcription.geometry.so3 import log_so3

    if not np.all(np.isfinite(XN)):
        return {}
    s = unpack_states(XN[None])
    if prob.Xd is not None:
        d = unpack_states(prob.Xd[None])
        return {"attitude_miss_deg": float(np.degrees(np.linalg.norm(np.asarray(log_so3(d.R[0].T @ s.R[0]), float)))),
                "rate_miss": float(np.linalg.norm(np.linalg.solve(prob.model.inertia, s.Pi[0] - d.Pi[0])))}
    rd, mu = prob.terminal.radius, prob.model.mu
    return {"radius_miss": float(abs(np.linalg.norm(s.x[0]) - rd)),
            "speed_miss": float(abs(np.linalg.norm(s.gamma[0]) / prob.model.mass - np.sqrt(mu / rd)))}


def _peer_state(p, prob) -> np.ndarray:
    """The peer's own final node state in our layout (18), for its terminal error as the NLP sees it."""
    from se3ocp.transcription.geometry.state import pack_state

    ts = "traj.phase0.timeseries."
    q = p.get_val(ts + "q")[-1]
    w = p.get_val(ts + "w")[-1]
    orbit = prob.model.mu is not None
    x = p.get_val(ts + "r")[-1] if orbit else prob.X0[0:3]
    v = p.get_val(ts + "v")[-1] if orbit else prob.X0[3:6] / prob.model.mass
    return pack_state(x, prob.model.mass * v, quat_to_R(q), prob.model.inertia @ w)


def _instrument(driver) -> dict:
    """Measurement only: a dict that receives the time the optimizer starts (after OpenMDAO's set-up, its
    initial run and the colourings), its iterations and its status, from SLSQP (scipy) or IPOPT (modOpt)."""
    info: dict = {"iterations": 0, "status": "", "optimizer": "scipy SLSQP"}
    if isinstance(driver, om.ScipyOptimizeDriver):
        objfunc = driver._objfunc

        def first(x):
            info.setdefault("start", time.perf_counter())
            return objfunc(x)
        driver._objfunc = first
        run = driver.run

        def done():
            fail = run()
            res = driver._scipy_optimize_result
            info.update(iterations=int(getattr(res, "nit", 0)), status=str(getattr(res, "message", "")))
            return fail
        driver.run = done
        return info
    import modopt

    solve = modopt.IPOPT.solve
    info["optimizer"] = f"IPOPT (modOpt {_version('modopt')}, limited-memory Hessian)"

    def timed(self):
        info["start"] = time.perf_counter()
        out = solve(self)
        info.update(iterations=int(out["iterations"]), status=str(out["return_status"]))
        return out
    modopt.IPOPT.solve = timed
    return info


def solve_peer(case: str, N: int) -> dict:
    """Build and solve the Dymos model of ``case`` at N (a multiple of 3); returns a bench record.

    build = set-up up to the optimizer's start (OpenMDAO set-up, the initial run, the partial and total
    colourings); solve = the optimizer's start to the end of ``run_driver``."""
    import os
    import tempfile

    from se3ocp.transcription.ocp import terminal_error

    prob = _problem(case, N)
    slew = prob.control.objective.free_time
    guess = slew_guess(prob, N) if slew else orbit_raise_guess(prob, N)
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:     # OpenMDAO writes its colouring files to the working directory
        os.chdir(tmp)
        try:
            t0 = time.perf_counter()
            p, phase = (build_slew if slew else build_orbit_raise)(prob, N, guess)
            info = _instrument(p.driver)
            p.run_driver()
            t_end = time.perf_counter()
        finally:
            os.chdir(here)
    start = info.get("start", t0)
    ts = "traj.phase0.timeseries."
    t = p.get_val(ts + "time").ravel()
    T = float(t[-1])
    rec = {"method": "dymos", "solver": f"dymos {_version('dymos')} Radau({N // ORDER}x{ORDER}) + {info['optimizer']}",
           "build_s": start - t0, "solve_s": t_end - start, "iterations": info["iterations"],
           "converged": not p.driver.fail, "status": info["status"], "T": T,
           "cost": T if slew else float(p.get_val(ts + "J")[-1, 0])}
    rec["nlp_terminal_error"] = terminal_error(_peer_state(p, prob), prob)
    if slew:
        f, breaks = radau_controls(phase, t, {"tau": p.get_val(ts + "tau")})
        control = lambda s: np.concatenate([np.zeros(3), f["tau"](s)])   # noqa: E731
    else:
        f, breaks = radau_controls(phase, t, {k: p.get_val(ts + k) for k in ("s_f", "d_f", "s_m", "d_m")})
        control = lambda s: np.concatenate([f["s_f"](s) * f["d_f"](s), f["s_m"](s) * f["d_m"](s)])  # noqa: E731
    return _finish(_reflown(rec, prob, control, breaks, T))


def run_ours(case: str, N: int) -> dict:
    """Our direct method with its default settings on the same maneuver file at N steps, its controls
    re-flown by the same DOP853 code."""
    import se3ocp

    s = se3ocp.solve(se3ocp.load(ROOT / "configs" / f"{STEMS[case]}.yaml", [f"horizon.N={N}"]), "direct")
    rec = {"method": "se3ocp", "solver": f"se3ocp {_version('se3ocp')} direct ({s.problem.scheme})",
           "build_s": float(s.build_s), "solve_s": float(s.solve_s), "iterations": int(s.iterations),
           "converged": bool(s.converged), "status": s.result.value, "cost": float(s.cost), "T": float(s.T),
           "nlp_terminal_error": float(s.terminal_error)}
    prob = s.problem.replace(T=float(s.T))
    control, breaks = hold(np.asarray(s.control_times, float), np.asarray(s.controls, float))
    return _finish(_reflown(rec, prob, control, breaks, float(s.T)))


def _version(pkg: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(pkg)
    except PackageNotFoundError:
        return "?"


def _finish(rec: dict) -> dict:
    """The record with the load average (1, 5, 15 min) at its end: the machine may be shared."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from benchkit import load

    rec["load"] = load()
    return rec


def compare(cases: list[str], Ns: list[int], runs: int, timeout: float) -> list[dict]:
    """Ours and the peer, fresh processes, round-robin (benchkit.round_robin); the published optimum beside."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from benchkit import round_robin

    def line(r, k, rec):
        print(f"  run {r + 1} {k[0]:11s} N={k[1]:4d} {k[2]:5s} {rec.get('status', '?')[:30]!s:30s} it "
              f"{rec.get('iterations', '-')!s:>5} build {rec.get('build_s', float('nan')):7.2f} s solve "
              f"{rec.get('solve_s', float('nan')):8.2f} s objective {rec.get('cost', float('nan')):.10g} "
              f"re-flown terminal error {rec.get('terminal_error', float('nan')):.1e} load {rec.get('load', '?')}",
              flush=True)

    out = round_robin(Path(__file__).resolve(), cases, Ns, runs, timeout,
                      ("cost", "T", "terminal_error", "nlp_terminal_error", "bound_violation", *MISSES), line)
    for rec in out:
        rec["published"] = PUBLISHED.get(rec["case"])
    print_table(out, runs)
    return out


def print_table(out: list[dict], runs: int) -> None:
    """The --compare table (Markdown)."""
    print(f"\nmedians of {runs} fresh-process run(s) each; ratio = peer / ours; objective: T (slews) or fuel")
    print("| maneuver | N | ours: it / build s / solve s | peer: it / build s / solve s | solve ratio | "
          "build+solve ratio | objective ours / peer (published) | re-flown terminal error ours / peer (DOP853) | "
          "peer's control over its bound between nodes |")
    print("|---|---|---|---|---|---|---|---|---|")

    def ratio(x):
        return "-" if x is None else f"{x:.0f}x"

    def cost(r):
        return f"{r['cost']:.8g}" if r.get("converged") else "-"

    def miss(r):
        if "attitude_miss_deg" in r:
            return f"{r['terminal_error']:.1e} ({r['attitude_miss_deg']:.1e} deg, {r['rate_miss']:.1e} rad/s)"
        if "radius_miss" in r:
            return f"{r['terminal_error']:.1e} (radius {r['radius_miss']:.1e}, speed {r['speed_miss']:.1e})"
        return f"{r['terminal_error']:.1e}"

    for r in out:
        if "ours" not in r:
            print(f"| {r['case']} | {r['N']} | {r['status']} |")
            continue
        o, p = r["ours"], r["peer"]
        pub = f" ({r['published']})" if r.get("published") else ""
        note = "" if p["converged"] else f" ({p['status'][:40]})"
        print(f"| {r['case']} | {r['N']} | {o['iterations']} / {o['build_s']:.2f} / {o['solve_s']:.2f} | "
              f"{p['iterations']} / {p['build_s']:.2f} / {p['solve_s']:.2f}{note} | {ratio(r['solve_ratio'])} | "
              f"{ratio(r['total_ratio'])} | {cost(o)} / {cost(p)}{pub} | "
              f"{miss(o)} / {miss(p)} | {p.get('bound_violation', float('nan')):.2g} |")


if __name__ == "__main__":
    import argparse
    import json

    ap = argparse.ArgumentParser(description="the Dymos peer (see the module docstring)")
    ap.add_argument("case", nargs="?", default="slew", choices=sorted(STEMS))
    ap.add_argument("N", nargs="?", type=int, default=30)
    ap.add_argument("--ours", action="store_true", help="run ours instead of the peer (one case)")
    ap.add_argument("--compare", default=None, help="comma separated cases: ours against the peer, fresh processes")
    ap.add_argument("--N", dest="Ns", default="30,60", help="with --compare: comma separated N (multiples of 3)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=3600.0, help="with --compare: seconds per run")
    ap.add_argument("--json", default=None, help="with --compare: write the records to this file")
    ap.add_argument("--one", nargs=3, metavar=("CASE", "N", "WHO"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        case, N, who = a.one[0], int(a.one[1]), a.one[2]
        print(json.dumps(run_ours(case, N) if who == "ours" else solve_peer(case, N)))
    elif a.compare:
        cases = [c for c in a.compare.split(",") if c]
        Ns = [int(n) for n in a.Ns.split(",")]
        bad = [c for c in cases if c not in STEMS] + [f"N={n}" for n in Ns if n < ORDER or n % ORDER]
        if bad:
            print(f"peer_dymos.py: --compare/--N: expected cases from {sorted(STEMS)} and N multiples of {ORDER}, "
                  f"got {', '.join(bad)}", file=sys.stderr)
            sys.exit(2)
        recs = compare(cases, Ns, a.runs, a.timeout)
        if a.json:
            Path(a.json).write_text(json.dumps(recs, indent=1))
    else:
        print(json.dumps(run_ours(a.case, a.N) if a.ours else solve_peer(a.case, a.N), indent=1))
