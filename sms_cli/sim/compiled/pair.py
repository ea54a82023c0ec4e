"""One RKMK4 step of the two-spacecraft plant (``sms_cli.formation.plant.TwoBodyPlant.step``, the reference) in a
single compiled call, with the wrenches between the two bodies evaluated inside it at every stage.

The two free-flyers are coupled only through those wrenches, so the pair is a forest of two single-root trees:
each body's model flattened by ``tree.flatten``, body 2's arrays after body 1's with their joint, q and v
indices shifted; the combined layout is TwoBodyPlant's ``q = [q₁ | q₂]``, ``v = [v₁ | v₂]`` and forest joint i is
the combined model's joint i + 1. ``dynamics.aba`` solves each root's 6×6 block on its own, so the ONE ABA gives
both bodies' accelerations; a frame wrench enters through the generalized forces, τ += J_frameᵀ F (the force
carried from the frame to the root along the frame's chain, every DoF of that body including its base's 6).
Body inertias are read from the combined Pinocchio model (the thrusters' tanks change a base's mass there:
``refresh_body``).

The wrenches at a stage (q, v), ``[f; τ]`` (N, N m) in a frame's LOCAL axes at its origin:

- the internal pair's reaction: on body 1's base frame, ``−Ad_{g12}^{-T} F2`` (F2 in body 2's base frame,
  g12 = g1⁻¹ g2 the stage's relative base pose), ``FormationSimulation``'s internal pair;
- the capture spring-damper between frames a and b (``sms_cli.formation.capture.interface_wrenches``):
  ``F_b = −Jlog6(g_e)ᵀ K e − D V_rel``, ``F_a = −Ad_{b←a}ᵀ F_b``, e = log6(g_t⁻¹ g_a⁻¹ g_b),
  V_rel = V_b − Ad_{b←a} V_a.

Same results as ``TwoBodyPlant.step`` to round-off (tests/test_compiled_pair.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sms_cli.sim.compiled import HOT, JIT
from sms_cli.sim.compiled.dynamics import (
    aba,
    body_velocities,
    compose,
    dexpinv_neg,
    force_act,
    integrate,
    joint_transforms,
    motion_act_inv,
    rk4_advance,
    rk4_combine,
    world_placements,
)
from sms_cli.sim.compiled.se3 import jlog6, log6
from sms_cli.sim.compiled.tree import FREE_FLYER, PRISMATIC

# rows of the frame table the step reads (``PairPlant.frames``)
REACTION_FRAME, CAPTURE_A, CAPTURE_B = 0, 1, 2


# ----------------------------------------------------------------------------- kernels
@njit(**HOT)
def add_frame_wrench(parent, kind, axis, idx_v, R_rel, p_rel, joint, fR, fp, F, tau, f, g):
    """tau += J_frameᵀ F: the wrench F (6, frame LOCAL axes at its origin) on the frame placed (fR, fp) in joint
    ``joint``, carried joint by joint to its tree's root (R_rel, p_rel: ``joint_transforms``); f, g: 6 scratch."""
    force_act(fR, fp, F, f)
    i = joint
    while True:
        iv = idx_v[i]
        if kind[i] == FREE_FLYER:
            for a in range(6):
                tau[iv + a] += f[a]
            return
        off = 0 if kind[i] == PRISMATIC else 3
        tau[iv] += axis[i, 0] * f[off] + axis[i, 1] * f[off + 1] + axis[i, 2] * f[off + 2]
        force_act(R_rel[i], p_rel[i], f, g)
        for a in range(6):
            f[a] = g[a]
        i = parent[i]


@njit(**HOT)
def _inverse_compose(R1, p1, R2, p2, R_out, p_out):
    """(R_out, p_out) = (R1, p1)⁻¹ · (R2, p2): rotation R1ᵀ R2, translation R1ᵀ (p2 − p1)."""
    for a in range(3):
        p_out[a] = R1[0, a] * (p2[0] - p1[0]) + R1[1, a] * (p2[1] - p1[1]) + R1[2, a] * (p2[2] - p1[2])
        for b in range(3):
            R_out[a, b] = R1[0, a] * R2[0, b] + R1[1, a] * R2[1, b] + R1[2, a] * R2[2, b]


@njit(**HOT)
def capture_wrench_pair(parent, kind, axis, idx_v, R_rel, p_rel, v, f_joint, f_R, f_p, target_R, target_p, K, D, ws, pws):
    """The capture interface's wrenches at the joint transforms (R_rel, p_rel) and the velocity v
    (``sms_cli.formation.capture.interface_wrenches``): F_b = −Jlog6(g_e)ᵀ K e − D V_rel into ``pws[3][6]`` (frame b)
    and F_a = −Ad_{b←a}ᵀ F_b into ``pws[3][7]`` (frame a), each in its frame's LOCAL axes at its origin."""
    vel, Rs, ps, V, J, C = pws
    oR, op = ws[16], ws[17]
    world_placements(parent, R_rel, p_rel, oR, op)
    body_velocities(parent, kind, axis, R_rel, p_rel, idx_v, v, vel)
    ja, jb = f_joint[CAPTURE_A], f_joint[CAPTURE_B]
    compose(oR[ja], op[ja], f_R[CAPTURE_A], f_p[CAPTURE_A], Rs[1], ps[1])  # g_a
    compose(oR[jb], op[jb], f_R[CAPTURE_B], f_p[CAPTURE_B], Rs[2], ps[2])  # g_b
    _inverse_compose(Rs[1], ps[1], Rs[2], ps[2], Rs[3], ps[3])  # g_ab = g_a⁻¹ g_b
    _inverse_compose(target_R, target_p, Rs[3], ps[3], Rs[4], ps[4])  # g_e = g_t⁻¹ g_ab
    motion_act_inv(f_R[CAPTURE_A], f_p[CAPTURE_A], vel[ja], V[1])  # V_a (frame a)
    motion_act_inv(f_R[CAPTURE_B], f_p[CAPTURE_B], vel[jb], V[2])  # V_b (frame b)
    motion_act_inv(Rs[3], ps[3], V[1], V[3])  # Ad_{b←a} V_a = g_ab⁻¹ acting on V_a
    log6(Rs[4], ps[4], V[4])  # e
    jlog6(Rs[4], ps[4], J, C)
    for a in range(6):
        ke = 0.0
        for b in range(6):
            ke += K[a, b] * V[4, b]
        V[5, a] = ke  # K e
    for a in range(6):
        x = 0.0
        for b in range(6):
            x -= J[b, a] * V[5, b] + D[a, b] * (V[2, b] - V[3, b])
        V[6, a] = x  # F_b
    force_act(Rs[3], ps[3], V[6], V[7])  # Ad_{b←a}ᵀ F_b = F_b in frame a (g_ab acting on it)
    for a in range(6):
        V[7, a] = -V[7, a]  # F_a


@njit(**HOT)
def interface_forces(parent, kind, axis, idx_v, roots, R_rel, p_rel, v, f_joint, f_R, f_p, reaction, F2, capture,
                     target_R, target_p, K, D, tau, ws, pws):
    """tau += the generalized forces of the reaction (``reaction``: F2 (6), body 2's base frame) and of the capture
    interface (``capture``: target pose (target_R, target_p) of frame b in frame a, K, D 6×6) at the joint
    transforms (R_rel, p_rel) and the velocity v; frames: rows of (f_joint, f_R, f_p) (see the module docstring)."""
    vel, Rs, ps, V, J, C = pws
    f, g = V[8], V[9]
    if reaction:  # g12 = g1⁻¹ g2 from the roots' world placements; −Ad_{g12}^{-T} F2 on body 1's base frame
        r1, r2 = roots[0], roots[1]
        _inverse_compose(R_rel[r1], p_rel[r1], R_rel[r2], p_rel[r2], Rs[0], ps[0])
        force_act(Rs[0], ps[0], F2, V[0])
        for a in range(6):
            V[0, a] = -V[0, a]
        add_frame_wrench(parent, kind, axis, idx_v, R_rel, p_rel, f_joint[REACTION_FRAME], f_R[REACTION_FRAME],
                         f_p[REACTION_FRAME], V[0], tau, f, g)
    if capture:
        capture_wrench_pair(parent, kind, axis, idx_v, R_rel, p_rel, v, f_joint, f_R, f_p, target_R, target_p, K, D, ws, pws)
        ja, jb = f_joint[CAPTURE_A], f_joint[CAPTURE_B]
        add_frame_wrench(parent, kind, axis, idx_v, R_rel, p_rel, ja, f_R[CAPTURE_A], f_p[CAPTURE_A], V[7], tau, f, g)
        add_frame_wrench(parent, kind, axis, idx_v, R_rel, p_rel, jb, f_R[CAPTURE_B], f_p[CAPTURE_B], V[6], tau, f, g)


@njit(**JIT)
def pair_rkmk4_step(parent, kind, axis, place_R, place_p, inertia, leaf_IA, armature, idx_q, idx_v, roots,
                    q, v, tau, dt, f_joint, f_R, f_p, reaction, F2, capture, target_R, target_p, K, D,
                    q_out, v_out, ws, pws):
    """One RKMK4 step of size dt (s) of the two-tree forest (``sms_cli.formation.plant.rkmk4``: the dexp⁻¹
    correction on each root's 6-block) under the held generalized forces tau (nv; the bases' entries are their
    base wrenches), the interface wrenches (``interface_forces``) evaluated at every stage. ``roots``: the forest
    indices of the two free-flyers; ``ws``: ``dynamics.workspace`` of the forest; ``pws``: ``pair_workspace``."""
    nv = v.shape[0]
    st = ws[18]
    acc, th, vs, kk, ksum = st[0:4], st[4], st[5], st[6], st[7]
    qs, tau_s, root_dI, root_f = ws[19], ws[21], ws[22], ws[23]  # root_dI, root_f stay zero (no modes)
    R_rel, p_rel = ws[8], ws[9]
    for a in range(q.shape[0]):
        qs[a] = q[a]
    for a in range(nv):
        vs[a] = v[a]
        ksum[a] = 0.0
    for stage in range(4):
        if stage > 0:
            integrate(kind, axis, idx_q, idx_v, q, th, qs)
        joint_transforms(kind, axis, place_R, place_p, idx_q, qs, R_rel, p_rel)
        for a in range(nv):
            tau_s[a] = tau[a]
        if reaction or capture:
            interface_forces(parent, kind, axis, idx_v, roots, R_rel, p_rel, vs, f_joint, f_R, f_p, reaction, F2,
                             capture, target_R, target_p, K, D, tau_s, ws, pws)
        aba(parent, kind, axis, inertia, leaf_IA, armature, idx_v, R_rel, p_rel, vs, tau_s, root_dI, root_f,
            acc[stage], ws)
        if stage > 0:  # k2, k3, k4: dexp⁻¹ on each free-flyer's block (joints: identity)
            for r in range(roots.shape[0]):
                iv = idx_v[roots[r]]
                dexpinv_neg(th[iv:], vs[iv:], kk[iv:])
            if stage < 3:
                for a in range(nv):
                    ksum[a] += kk[a]  # k2 + k3
        if stage < 3:
            rk4_advance(stage, dt, v, acc, kk, th, vs)
    rk4_combine(dt, v, ksum, kk, acc, th, v_out)
    integrate(kind, axis, idx_q, idx_v, q, th, q_out)


@njit(**JIT)
def capture_wrenches(parent, kind, axis, place_R, place_p, idx_q, idx_v, q, v, f_joint, f_R, f_p, target_R, target_p, K,
                     D, out, ws, pws):
    """The capture interface's wrench pair at the state (q, v): out[0] = F_a (frame a), out[1] = F_b (frame b), each
    in its frame's LOCAL axes at its origin (``capture_wrench_pair``; what the capture monitor samples every step)."""
    R_rel, p_rel = ws[8], ws[9]
    joint_transforms(kind, axis, place_R, place_p, idx_q, q, R_rel, p_rel)
    capture_wrench_pair(parent, kind, axis, idx_v, R_rel, p_rel, v, f_joint, f_R, f_p, target_R, target_p, K, D, ws, pws)
    V = pws[3]
    for a in range(6):
        out[0, a] = V[7, a]
        out[1, a] = V[6, a]


def pair_workspace(n: int) -> tuple:
    """Scratch of ``interface_forces`` for a forest of n joints: body velocities (n×6), 5 poses, 10 six-vectors,
    Jlog6 (6×6) and its 3×3 block."""
    return (np.empty((n, 6)), np.empty((5, 3, 3)), np.empty((5, 3)), np.empty((10, 6)), np.empty((6, 6)),
            np.empty((3, 3)))


# ----------------------------------------------------------------------------- Python side
def unsupported_reason(plant) -> str | None:
    """Why the compiled pair step cannot step ``plant`` (a ``TwoBodyPlant``; None when it can)."""
    from sms_cli.sim.compiled.tree import unsupported_reason as tree_reason

    for b in plant.bodies:
        why = tree_reason(b.system.model)
        if why:
            return f"{b.name}: {why}"
        if not np.array_equal(plant.model.jointPlacements[b.base_joint_id].homogeneous, np.eye(4)):
            return f"{b.name}: its free-flyer joint is placed off the world origin"
    return None


class PairPlant:
    """Compiled RKMK4 steps of a ``TwoBodyPlant`` (see the module docstring). Frames are the plant's combined
    frame ids (frames added to the plant later, e.g. a capture interface, are read when first used)."""

    def __init__(self, plant):
        from sms_cli.sim.compiled.dynamics import workspace
        from sms_cli.sim.compiled.tree import flatten

        self.plant = plant
        trees = [flatten(b.system.model) for b in plant.bodies]
        n1, nq1, nv1 = trees[0].parent.size, trees[0].nq, trees[0].nv
        cat = np.concatenate

        def shifted(a, k):
            return a + k * (a >= 0) if k else a

        t1, t2 = trees
        self._structure = (cat([t1.parent, shifted(t2.parent, n1)]), cat([t1.kind, t2.kind]),
                           np.ascontiguousarray(cat([t1.axis, t2.axis])), np.ascontiguousarray(cat([t1.place_R, t2.place_R])),
                           np.ascontiguousarray(cat([t1.place_p, t2.place_p])))
        self._armature = cat([t1.armature, t2.armature])
        self._idx = (cat([t1.idx_q, t2.idx_q + nq1]), cat([t1.idx_v, t2.idx_v + nv1]))
        self.roots = np.array([0, n1], dtype=np.int64)
        self.n = n1 + t2.parent.size
        assert self.n == plant.model.njoints - 1 and self._idx[0][-1] < plant.nq and self._idx[1][-1] < plant.nv
        self.refresh()
        self._ws = workspace(self.n, plant.nq, plant.nv)
        self._pws = pair_workspace(self.n)
        self._frames: dict[tuple, tuple] = {}
        self._no_capture = (np.eye(3), np.zeros(3), np.zeros((6, 6)), np.zeros((6, 6)))

    def refresh(self) -> None:
        """Re-read every body inertia from the combined model (and the constant leaf inertias ABA uses)."""
        from sms_cli.sim.compiled.tree import _constant_leaf_inertias, spatial_inertia

        m = self.plant.model
        inertia = np.array([spatial_inertia(m.inertias[j].mass, m.inertias[j].lever, m.inertias[j].inertia)
                            for j in range(1, self.n + 1)])
        parent, kind, axis, place_R, place_p = self._structure
        leaf = _constant_leaf_inertias(parent, kind, axis, place_R, place_p, inertia, self._armature, self._idx[1])
        self._tree = (parent, kind, axis, place_R, place_p, inertia, leaf, self._armature, *self._idx)

    def refresh_body(self, joint_id: int) -> None:
        """Re-read the inertia of combined joint ``joint_id``'s body in place (a base losing propellant); a body whose
        articulated inertia ABA precomputes (a constant leaf) gets the full ``refresh``."""
        from sms_cli.sim.compiled.tree import spatial_inertia

        i = joint_id - 1
        if not np.isnan(self._tree[6][i, 0, 0]):
            self.refresh()
            return
        Y = self.plant.model.inertias[joint_id]
        self._tree[5][i] = spatial_inertia(Y.mass, Y.lever, Y.inertia)

    def frames(self, frame_a: int = 0, frame_b: int = 0) -> tuple:
        """(forest joint, R, p) of body 1's base frame (the reaction's) and the capture frames a, b (combined ids)."""
        key = (frame_a, frame_b)
        if key not in self._frames:
            from sms_cli.sim.compiled.tree import frame_table

            self._frames[key] = frame_table(self.plant.model, [self.plant.bodies[0].base_frame_id, frame_a, frame_b])
        return self._frames[key]

    def step(self, q: np.ndarray, v: np.ndarray, dt: float, tau: np.ndarray, base_wrenches=(None, None),
             reaction: np.ndarray | None = None, capture: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
        """One RKMK4 step of dt (s): ``TwoBodyPlant.step`` with tau (nv; the bases' entries ignored) and the base
        wrenches (F1, F2; None: zero) held, and the interface wrenches at every stage: ``reaction`` F2 (6, body 2's
        base frame; None: none) and ``capture`` = (frame a, frame b (combined ids), target pose g_t (pin.SE3) of b
        in a, K, D (6×6)) (None: none)."""
        t = np.array(tau, dtype=float)
        for s, F in zip(self.plant.base_blocks, base_wrenches):
            t[s] = 0.0 if F is None else F
        if capture is None:
            frames, (tR, tp, K, D) = self.frames(), self._no_capture
        else:
            fa, fb, target, K, D = capture
            frames = self.frames(fa, fb)
            tR, tp = np.ascontiguousarray(target.rotation), np.array(target.translation)
            K, D = np.ascontiguousarray(K, dtype=float), np.ascontiguousarray(D, dtype=float)
        F2 = np.zeros(6) if reaction is None else np.ascontiguousarray(reaction, dtype=float)
        q_out, v_out = np.empty(self.plant.nq), np.empty(self.plant.nv)
        pair_rkmk4_step(*self._tree, self.roots, np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(v, dtype=float),
                        t, float(dt), *frames, reaction is not None, F2, capture is not None, tR, tp, K, D, q_out, v_out,
                        self._ws, self._pws)
        return q_out, v_out

    def capture_wrenches(self, q: np.ndarray, v: np.ndarray, capture: tuple) -> list:
        """[(frame a, F_a), (frame b, F_b)] at the state (q, v), as ``sms_cli.formation.capture.interface_wrenches``
        gives them (each wrench [f; τ] in its frame's LOCAL axes at its origin); ``capture`` as in ``step``."""
        fa, fb, target, K, D = capture
        out = np.empty((2, 6))
        parent, kind, axis, place_R, place_p, _, _, _, idx_q, idx_v = self._tree
        capture_wrenches(parent, kind, axis, place_R, place_p, idx_q, idx_v, np.ascontiguousarray(q, dtype=float),
                         np.ascontiguousarray(v, dtype=float), *self.frames(fa, fb), np.ascontiguousarray(target.rotation),
                         np.array(target.translation), np.ascontiguousarray(K, dtype=float),
                         np.ascontiguousarray(D, dtype=float), out, self._ws, self._pws)
        return [(fa, out[0]), (fb, out[1])]

    def warm_call(self):
        """The step's kernel call on a throw-away state (``sms_cli.sim.compiled.warmup``): one signature for every
        interface kind (the interface is chosen by two flags)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        q = np.concatenate([b.system.q0 for b in self.plant.bodies]).astype(float)
        v = np.zeros(self.plant.nv)
        tR, tp, K, D = self._no_capture
        return KernelCall(f"{__name__}:pair_rkmk4_step",
                          (*self._tree, self.roots, q, v, np.zeros(self.plant.nv), 0.01, *self.frames(), False, np.zeros(6),
                           False, tR, tp, K, D, q.copy(), v.copy(), self._ws, self._pws), cost=12.0)

    def capture_warm_call(self):
        """``capture_wrenches``'s kernel call on a throw-away state (``sms_cli.sim.compiled.warmup``)."""
        from sms_cli.sim.compiled.warmup import KernelCall

        parent, kind, axis, place_R, place_p, _, _, _, idx_q, idx_v = self._tree
        q = np.concatenate([b.system.q0 for b in self.plant.bodies]).astype(float)
        tR, tp, K, D = self._no_capture
        return KernelCall(f"{__name__}:capture_wrenches",
                          (parent, kind, axis, place_R, place_p, idx_q, idx_v, q, np.zeros(self.plant.nv), *self.frames(),
                           tR, tp, K, D, np.empty((2, 6)), self._ws, self._pws), cost=4.0)
