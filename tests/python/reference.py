"""An independent reference solution of docs/model.md's equations, for the tests.

Deliberately not the FMU's formulation: the constraint is handled with a Lagrange
multiplier (J·ω̇ − Gᵀλ = Q, G·ω̇ = −Ġ·ω, one 5×5 solve per evaluation), every geometric
term is derived from the pin vectors in Cartesian form rather than from the B1/C1 formulas,
the initial assembly is found by a numerical root search, and there is no projection.
Integrated by scipy's DOP853 at rtol = atol = 1e-12 (or as asked).
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

PAPER_LAWS = dict(Mm_a0=100.0, Mm_a1=-20.0, Mm_a2=-1.0, Mr_b0=20.0, Mr_b1=-0.05)
# No torque at all: the built-in laws off (the inputs stay at 0).
NO_LAWS = dict(builtin_laws=False)
# The 100 s free run: spring windings and pushes, no torque, no damper.
FREE_RUN = dict(NO_LAWS, omega2_0=6.0, twist12_0=0.2, twist34_0=-0.1, omega4_0=-1.0)


@dataclass
class Params:
    J: tuple = (0.5, 0.2, 0.3, 0.7)
    k12: float = 100.0
    k34: float = 100.0
    d12: float = 0.0
    d34: float = 0.0
    c4: float = 0.0
    l: float = 0.5
    l2: float = 0.05
    l3: float = 0.5
    L: float = 0.7
    phi2_0: float = 0.0
    phi3_guess: float = np.pi / 2
    twist12_0: float = 0.0
    twist34_0: float = 0.0
    omega1_0: float = 0.0
    omega2_0: float = 0.0
    omega4_0: float = 0.0
    # The FMU's interface: the paper's laws by default, off with builtin_laws=False.
    Mm_a0: float = 100.0
    Mm_a1: float = -20.0
    Mm_a2: float = -1.0
    Mr_b0: float = 20.0
    Mr_b1: float = -0.05
    builtin_laws: bool = True
    M_m: float = 0.0  # constant inputs
    M_r: float = 0.0
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_fmu_values(cls, values):
        """Build from the FMU's start-value names (J1..J4 and the rest)."""
        values = dict(values)
        J = tuple(values.pop(f"J{i}", d) for i, d in zip(range(1, 5), cls.J))
        return cls(J=J, **values)


def pins(p, phi2, phi3):
    """Pin positions A2, A3 and their derivatives with respect to the angles."""
    u2 = np.array([np.cos(phi2), np.sin(phi2)])
    u3 = np.array([np.cos(phi3), np.sin(phi3)])
    n2 = np.array([-np.sin(phi2), np.cos(phi2)])
    n3 = np.array([-np.sin(phi3), np.cos(phi3)])
    A2 = p.l2 * u2
    A3 = np.array([p.l, 0.0]) + p.l3 * u3
    return A2, A3, u2, u3, n2, n3


def torques(p, w1):
    if not p.builtin_laws:
        return p.M_m, p.M_r
    motor = p.M_m + p.Mm_a0 + p.Mm_a1 * w1 + p.Mm_a2 * w1**2
    load = p.M_r + p.Mr_b0 + p.Mr_b1 * w1
    return motor, load


def rhs(t, y, p):
    phi1, phi2, phi3, phi4, w1, w2, w3, w4 = y
    A2, A3, u2, u3, n2, n3 = pins(p, phi2, phi3)
    d = A2 - A3
    # ḋ = l2·n2·ω2 − l3·n3·ω3; G = ∂(½|d|²)/∂φ = (0, d·l2·n2, −d·l3·n3, 0).
    d_dot = p.l2 * n2 * w2 - p.l3 * n3 * w3
    G = np.array([0.0, d @ (p.l2 * n2), -(d @ (p.l3 * n3)), 0.0])
    # d/dt(G·ω) = G·ω̇ + |ḋ|² + d·(−l2·u2·ω2² + l3·u3·ω3²): the rest moves to the right.
    gamma = -(d_dot @ d_dot + d @ (-p.l2 * u2 * w2**2 + p.l3 * u3 * w3**2))
    motor, load = torques(p, w1)
    s12 = p.k12 * (phi2 - phi1) + p.d12 * (w2 - w1)
    s34 = p.k34 * (phi3 - phi4) + p.d34 * (w3 - w4)
    Q = np.array([motor + s12, -s12, -s34, s34 - load - p.c4 * w4])
    K = np.zeros((5, 5))
    K[:4, :4] = np.diag(p.J)
    K[:4, 4] = -G
    K[4, :4] = G
    sol = np.linalg.solve(K, np.append(Q, gamma))
    return np.concatenate([[w1, w2, w3, w4], sol[:4]])


def closure(p, phi2, phi3):
    A2, A3, *_ = pins(p, phi2, phi3)
    return np.hypot(*(A2 - A3)) - p.L


def initial_state(p):
    """Assembly by root search: the root of the closure nearest phi3_guess."""
    grid = p.phi3_guess + np.linspace(-np.pi, np.pi, 2001)
    values = [closure(p, p.phi2_0, x) for x in grid]
    roots = [brentq(lambda x: closure(p, p.phi2_0, x), a, b, xtol=1e-15, rtol=1e-15)
             for a, b, fa, fb in zip(grid, grid[1:], values, values[1:]) if fa * fb < 0]
    phi3 = min(roots, key=lambda r: abs(r - p.phi3_guess))
    A2, A3, u2, u3, n2, n3 = pins(p, p.phi2_0, phi3)
    d = A2 - A3
    # Velocity constraint: d·(l2·n2·ω2 − l3·n3·ω3) = 0.
    w3 = (d @ (p.l2 * n2)) / (d @ (p.l3 * n3)) * p.omega2_0
    return np.array([p.phi2_0 + p.twist12_0, p.phi2_0, phi3, phi3 - p.twist34_0,
                     p.omega1_0, p.omega2_0, w3, p.omega4_0])


def energy(p, y):
    phi1, phi2, phi3, phi4 = y[:4]
    return 0.5 * np.dot(p.J, np.asarray(y[4:]) ** 2) + 0.5 * p.k12 * (phi1 - phi2) ** 2 \
        + 0.5 * p.k34 * (phi3 - phi4) ** 2


def solve(p, times, rtol=1e-12, method="DOP853"):
    """Reference states at `times` (rows: time, columns: φ1..φ4, ω1..ω4)."""
    y0 = initial_state(p)
    sol = solve_ivp(rhs, (times[0], times[-1]), y0, method=method, t_eval=times,
                    rtol=rtol, atol=rtol, args=(p,))
    assert sol.success, sol.message
    return sol.y.T


@dataclass(frozen=True)
class Motor:
    """A DC motor on body 1 (examples/dc_motor): L·di/dt = V − R·i − k·ω1, torque k·i; the
    voltage V, or piecewise linear through `V_table` ((times), (values)), held beyond it."""
    R: float = 0.5
    L: float = 0.01
    k: float = 2.0
    V: float = 24.0
    V_table: tuple = ()

    def voltage(self, t):
        return np.interp(t, *self.V_table) if self.V_table else self.V


def rhs_with_motor(t, y, p, motor):
    """The mechanism and the motor as one ODE: y = φ1..φ4, ω1..ω4, i; the motor's torque is
    the input M_m, exactly, at every instant (no coupling step)."""
    current = y[8]
    mechanism = rhs(t, y[:8], replace(p, M_m=motor.k * current))
    di = (motor.voltage(t) - motor.R * current - motor.k * y[4]) / motor.L
    return np.append(mechanism, di)


def solve_with_motor(p, motor, times, rtol=1e-12):
    """The monolithic reference of the motor-driven mechanism at `times` (columns φ1..φ4,
    ω1..ω4, i), the current starting at 0."""
    y, rows = np.append(initial_state(p), 0.0), []
    # Piece by piece between the voltage's breakpoints, where its slope jumps.
    breaks = motor.V_table[0] if motor.V_table else ()
    edges = sorted({times[0], times[-1], *(b for b in breaks if times[0] < b < times[-1])})
    for a, b in zip(edges, edges[1:]):
        inside = [t for t in times if a <= t < b] + ([b] if b == times[-1] else [])
        sol = solve_ivp(rhs_with_motor, (a, b), y, method="DOP853", t_eval=inside,
                        rtol=rtol, atol=rtol, args=(p, motor), dense_output=True)
        assert sol.success, sol.message
        rows.append(sol.y.T)
        y = sol.sol(b)
    return np.vstack(rows)


@dataclass(frozen=True)
class Flywheel:
    """A flywheel on a torsional shaft driven by body 4 (examples/flywheel_load): twist' =
    ω4 − w, J·w' = M − c·w, and M = k·twist + d·(ω4 − w) resisting body 4."""
    k: float = 2000.0
    d: float = 2.0
    J: float = 0.5
    c: float = 1.0


def rhs_with_flywheel(t, y, p, load):
    """The mechanism and the flywheel load as one ODE: y = φ1..φ4, ω1..ω4, twist, w; the
    shaft's torque is the input M_r, exactly, at every instant."""
    twist, w = y[8], y[9]
    torque = load.k * twist + load.d * (y[7] - w)
    mechanism = rhs(t, y[:8], replace(p, M_r=torque))
    return np.concatenate([mechanism, [y[7] - w, (torque - load.c * w) / load.J]])


def solve_with_flywheel(p, load, times, rtol=1e-12):
    """The monolithic reference of the mechanism driving the flywheel load at `times`
    (columns φ1..φ4, ω1..ω4, twist, flywheel speed), the shaft relaxed and the flywheel at
    rest at the start."""
    y0 = np.append(initial_state(p), [0.0, 0.0])
    sol = solve_ivp(rhs_with_flywheel, (times[0], times[-1]), y0, method="DOP853", t_eval=times,
                    rtol=rtol, atol=rtol, args=(p, load))
    assert sol.success, sol.message
    return sol.y.T
