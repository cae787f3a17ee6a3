"""Collision detection of the robot disc against the true obstacles and the workspace boundary.

The *clearance* of the robot disc (radius ``r``) at a centre ``q`` is

    c(q) = min( min_i d_i(q), -d_W(q) ) - r

with ``d_i`` the exact signed distance to obstacle ``i`` (negative inside) and ``d_W`` the one
to the workspace boundary (negative inside the workspace). The disc is in collision when
``c(q) < contact_tol`` (default 1e-6 m: touching counts). ``c`` is 1-Lipschitz in ``q``.

Swept check (the guarantee). Over a step the centre moves along an arc of length ``|v| t``
(see :mod:`service.sim.kinematics`), so ``|q(t) - q(t')| <= |v| |t - t'|``. An interval
``[t_a, t_b]`` whose end clearances satisfy ``c_a, c_b >= contact_tol`` and
``c_a + c_b >= |v| (t_b - t_a)`` is *certified*: every point of it lies in one of the two
balls of radius ``c_a`` or ``c_b`` around the ends, which hold no obstacle. :meth:`sweep`
starts from ``[0, dt]`` and bisects every uncertified interval (all midpoints of a round are
evaluated in one vectorised call) until every interval before the first sample in contact is
certified and that contact is localised to ``contact_tol / |v|`` seconds. Hence a step that
reports no contact is collision-free along its whole arc (no tunnelling through thin walls at
any speed), and a contact is found at most ``contact_tol`` metres (of path) late. If more than
``max_samples`` clearances would be needed (a path grazing a wall within a few contact
tolerances), the step is conservatively stopped at the start of the first uncertified interval
and reported as a contact.

Clearances are exact (to 1e-9 m) where they matter: each query computes cheap bounds (bounding
and inscribed circles of the obstacles; an inscribed square and ellipse and the bounding
rectangle of the workspace), then the distance to boundary samples (within half a sample
spacing of the truth), then the exact distance (:class:`service.sim._shapes.ExactDistance`)
for every squircle that can still be the nearest one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navigation.geometry import ExactDistance, Squircle, beta_rows

from .kinematics import arc_positions

__all__ = ["ClearanceMap", "Sweep", "WORKSPACE"]

#: owner index of the workspace boundary in clearance results
WORKSPACE = -1


@dataclass(frozen=True, slots=True)
class Sweep:
    """Outcome of :meth:`ClearanceMap.sweep` for one step.

    Attributes
    ----------
    t_stop : float
        Time (s, within the step) of the pose the robot ends at: the full step when free, else
        the last certified collision-free sample before the contact.
    contact : bool
        Whether the motion reached a contact.
    t_contact : float
        Time of the (first) contact within the step, or ``nan`` without one.
    owner : int
        Obstacle index of the contact (``WORKSPACE`` = -1 for the boundary), -2 without one.
    min_clearance : float
        Smallest exact clearance sampled along the travelled part (``inf`` if none was below
        the step length; the end pose is evaluated separately).
    samples : int
        Clearance evaluations used.
    """

    t_stop: float
    contact: bool
    t_contact: float
    owner: int
    min_clearance: float
    samples: int


class ClearanceMap:
    """Clearance of a disc of ``radius`` against fixed obstacles and a workspace (immutable).

    Parameters
    ----------
    workspace : Squircle
    obstacles : sequence of Squircle
    radius : float
        Robot radius (m, >= 0).
    spacing : float
        Largest spacing of the boundary samples (m).
    """

    def __init__(self, workspace: Squircle, obstacles, radius: float, spacing: float = 0.005):
        self.workspace = workspace
        self.obstacles = tuple(obstacles)
        self.radius = float(radius)
        m = len(self.obstacles)
        self._m = m
        self._ed = ExactDistance(self.obstacles + (workspace,), spacing=spacing, split=m)
        self._c = np.array([o.center for o in self.obstacles], dtype=float).reshape(m, 2)
        self._R = np.array([o.bounding_radius for o in self.obstacles]).reshape(m)
        self._ins = np.array([o.inscribed_radius for o in self.obstacles]).reshape(m)
        w = workspace
        self._wp = self._ed.P[m]
        self._a = math.sqrt(1.0 / (1.0 + math.sqrt(1.0 - w.s ** 2)))  # inscribed square, normalised
        self._hmin = 0.5 * min(w.width, w.height)

    # ------------------------------------------------------------------ clearance
    def clearance(self, q, far: float = math.inf) -> tuple[np.ndarray, np.ndarray]:
        """Clearance of the disc at centres ``q (K, 2)`` and the nearest squircle of each.

        Returns ``(c (K,), owner (K,))``; ``owner`` is an obstacle index or ``WORKSPACE``.
        ``c`` is exact (1e-9 m) where it is below ``far``; elsewhere it may be a lower bound
        that is itself ``>= far``.
        """
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        K, m, r = len(q), self._m, self.radius
        # cheap bounds on the signed distances (workspace: positive inside)
        dc = np.sqrt(((q[:, None, :] - self._c[None, :, :]) ** 2).sum(-1))  # (K, m)
        p = self._wp
        dx, dy = q[:, 0] - p[0], q[:, 1] - p[1]
        u = np.abs(dx * p[2] + dy * p[3]) / p[4]
        w = np.abs(dy * p[2] - dx * p[3]) / p[5]
        lb_ws = np.maximum(self._hmin * (1.0 - np.hypot(u, w)),
                           np.where((u <= self._a) & (w <= self._a),
                                    np.minimum((self._a - u) * p[4], (self._a - w) * p[5]), -np.inf))
        ub_ws = np.minimum((1.0 - u) * p[4], (1.0 - w) * p[5])
        value = np.concatenate((dc - self._R, lb_ws[:, None]), axis=1)  # lower bounds (K, m + 1)
        ub = np.concatenate((dc - self._ins, ub_ws[:, None]), axis=1)
        U = np.minimum(ub.min(axis=1), far + r)
        k, j = np.nonzero(value < U[:, None])
        if k.size:
            d, h = self._ed.sampled(q[k], j)
            b = beta_rows(self._ed.P[j], q[k, 0], q[k, 1])
            neg = np.where(j < m, b < 0.0, b >= 0.0)  # inside an obstacle / outside the workspace
            lb2 = np.where(neg, -d, d - h)
            ub2 = np.where(neg, h - d, d)
            value[k, j] = lb2
            U2 = U.copy()
            np.minimum.at(U2, k, ub2)
            ex = (lb2 < U2[k]) | neg
            if np.any(ex):
                ke, je = k[ex], j[ex]
                s = self._ed.signed(q[ke], je)
                value[ke, je] = np.where(je < m, s, -s)
        owner = np.argmin(value, axis=1)
        c = value[np.arange(K), owner] - r
        return c, np.where(owner == m, WORKSPACE, owner)

    # ------------------------------------------------------------------ swept check
    def sweep(self, pose, v: float, omega: float, dt: float, c0: float, *, contact_tol: float = 1e-6,
              stop_margin: float = 1e-4, max_samples: int = 4096) -> Sweep:
        """Certify the arc of ``(v, omega)`` from ``pose`` over ``dt`` seconds, or find its first contact.

        ``c0`` is the clearance at ``pose`` (``>= contact_tol``). On a contact the robot stops at
        the latest certified sample before it whose clearance is at least
        ``min(stop_margin, c0)``, so that it can still move away afterwards. See the module
        docstring for the guarantee.
        """
        speed = abs(v)
        if speed == 0.0 or dt <= 0.0:
            return Sweep(dt, False, math.nan, -2, math.inf, 0)
        far = speed * dt + contact_tol
        t = np.array([0.0, dt])
        c_end, o_end = self.clearance(arc_positions(pose, v, omega, t[1:]), far)
        c = np.array([c0, c_end[0]])
        owner = np.array([-2, o_end[0]])
        used = 1
        capped_at = None
        while True:
            bad = np.nonzero(c < contact_tol)[0]
            first_bad = int(bad[0]) if bad.size else len(t)
            ta, tb = t[:first_bad], t[1:first_bad + 1]
            ca, cb = c[:first_bad], c[1:first_bad + 1]
            if first_bad == len(t):  # no contact sampled: every interval must be certified
                ta, tb, ca, cb = t[:-1], t[1:], c[:-1], c[1:]
            ok = (ca >= contact_tol) & (cb >= contact_tol) & (ca + cb >= speed * (tb - ta))
            split = ~ok
            if first_bad < len(t) and first_bad > 0:  # the interval ending at the contact
                split[-1] = speed * (tb[-1] - ta[-1]) > contact_tol
            idx = np.nonzero(split)[0]
            if idx.size == 0:
                break
            if used + idx.size > max_samples:
                capped_at = int(np.nonzero(~ok)[0][0])
                break
            mids = 0.5 * (ta[idx] + tb[idx])
            cm, om = self.clearance(arc_positions(pose, v, omega, mids), far)
            used += idx.size
            t = np.insert(t, idx + 1, mids)
            c = np.insert(c, idx + 1, cm)
            owner = np.insert(owner, idx + 1, om)
        bad = np.nonzero(c < contact_tol)[0]
        if capped_at is None and bad.size == 0:
            exact = c[1:][c[1:] < far]
            return Sweep(dt, False, math.nan, -2, float(exact.min()) if exact.size else math.inf, used)
        if capped_at is not None:
            i_contact = capped_at if not bad.size else min(capped_at, int(bad[0]))
            t_contact = float(t[i_contact])
            who = int(owner[int(bad[0])]) if bad.size else int(owner[i_contact])
            last = i_contact
        else:
            i_contact = int(bad[0])
            t_contact = float(t[i_contact])
            who = int(owner[i_contact])
            last = i_contact - 1
        keep = min(stop_margin, c0)
        good = np.nonzero(c[: last + 1] >= keep)[0]
        stop = int(good[-1]) if good.size else 0
        t_stop = float(t[stop])
        travelled = c[1: stop + 1]
        exact = travelled[travelled < far]
        low = float(exact.min()) if exact.size else math.inf
        if capped_at is None and i_contact > 0:
            # move the stop closer to the contact: every time before t[i_contact - 1] is certified
            # free, so any of them with clearance >= keep will do (head-on, k = 1.5 succeeds)
            tk = t_contact - np.array([1.5, 3.0, 6.0, 12.0, 24.0, 48.0]) * keep / speed
            tk = tk[(tk > t_stop) & (tk < t[i_contact - 1])]
            if tk.size:
                ck, _ = self.clearance(arc_positions(pose, v, omega, tk), far)
                used += tk.size
                ok = np.nonzero(ck >= keep)[0]
                if ok.size:
                    t_stop = float(tk[ok[0]])
                    low = min(low, float(ck[ok[0]:].min()))
        return Sweep(t_stop, True, t_contact, who, low, used)
