"""The sine and cosine polynomials of src/model/trig.rs: where their coefficients come from,
and how accurate they are as written there.

sin r = r + r·z·S(z) and cos r = 1 − z/2 + z²·C(z), z = r², |r| ≤ π/4, with S and C of
degree 5. Both are minimax fits for the relative error of sin r and cos r, found here by
Remez's exchange algorithm in 60-digit arithmetic; the test checks that trig.rs holds
that fit, and measures the error of its coefficients as the doubles written there.
"""

import pathlib
import re

import mpmath as mp
import pytest

TRIG_RS = pathlib.Path(__file__).resolve().parents[2] / "src" / "model" / "trig.rs"
DEGREE = 5
mp.mp.dps = 60
Z_MAX = (mp.pi / 4) ** 2


def sin_part(z):
    """S(z) exactly: (sin r − r)/(r·z)."""
    if z == 0:
        return mp.mpf(-1) / 6
    r = mp.sqrt(z)
    return (mp.sin(r) - r) / (r * z)


def sin_weight(z):
    """An error e in S(z) is an error r·z·e/sin r relative to sin r."""
    if z == 0:
        return mp.mpf(1)
    r = mp.sqrt(z)
    return r * z / mp.sin(r)


def cos_part(z):
    """C(z) exactly: (cos r − 1 + z/2)/z²."""
    if z == 0:
        return mp.mpf(1) / 24
    return (mp.cos(mp.sqrt(z)) - 1 + z / 2) / (z * z)


def cos_weight(z):
    """An error e in C(z) is an error z²·e/cos r relative to cos r."""
    return z * z / mp.cos(mp.sqrt(z))


FUNCTIONS = {"S": (sin_part, sin_weight), "C": (cos_part, cos_weight)}


def weighted_error(coefficients, f, w, z):
    value = mp.mpf(0)
    for c in reversed(coefficients):
        value = value * z + c
    return w(z) * (value - f(z))


def alternating_extrema(values):
    """Indices of the largest |value| in each run of one sign, ends included."""
    picked = []
    for j, v in enumerate(values):
        if picked and mp.sign(v) == mp.sign(values[picked[-1]]):
            if abs(v) > abs(values[picked[-1]]):
                picked[-1] = j
        elif v != 0:
            picked.append(j)
    return picked


def refined(g, a, b, steps=80):
    """Where |g| peaks in [a, b], by golden-section search."""
    ratio = (mp.sqrt(5) - 1) / 2
    for _ in range(steps):
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        if abs(g(c)) > abs(g(d)):
            b = d
        else:
            a = c
    return (a + b) / 2


def remez(f, w, lo, hi, iterations=10, grid=1000):
    """Degree-DEGREE minimax fit of f on [lo, hi] for the error weighted by w."""
    n = DEGREE + 2
    points = [(lo + hi) / 2 - (hi - lo) / 2 * mp.cos(mp.pi * i / (n - 1)) for i in range(n)]
    zs = [lo + (hi - lo) * mp.mpf(j) / grid for j in range(grid + 1)]
    for _ in range(iterations):
        # The fit that errs by ±E alternately at the points: n equations, n unknowns.
        matrix = mp.matrix(n, n)
        rhs = mp.matrix(n, 1)
        for i, z in enumerate(points):
            for k in range(DEGREE + 1):
                matrix[i, k] = z**k
            matrix[i, DEGREE + 1] = (-1) ** i / w(z)
            rhs[i] = f(z)
        solution = mp.lu_solve(matrix, rhs)
        coefficients = [solution[k] for k in range(DEGREE + 1)]
        values = [weighted_error(coefficients, f, w, z) for z in zs]
        extrema = alternating_extrema(values)
        while len(extrema) > n:
            # Drop the smaller end until n alternating extrema remain.
            extrema.pop(0 if abs(values[extrema[0]]) < abs(values[extrema[-1]]) else -1)
        # The ends stay; an interior extremum is sought between its grid neighbours.
        def error(z, fit=coefficients):
            return weighted_error(fit, f, w, z)

        points = [
            zs[j] if j in (0, grid) else refined(error, zs[j - 1], zs[j + 1]) for j in extrema
        ]
    return coefficients


def coefficients_in_trig_rs(name):
    text = TRIG_RS.read_text()
    block = re.search(rf"const {name}: \[f64; {DEGREE + 1}\] = \[(.*?)\];", text, re.S)
    assert block, f"trig.rs has no const {name} of {DEGREE + 1} entries"
    return [float(x) for x in re.findall(r"[-+0-9.e]+", block.group(1))]


def worst_relative_error(coefficients, f, w, samples=20_000):
    """The largest weighted error over [0, (π/4)²] of the coefficients as doubles."""
    exact = [mp.mpf(c) for c in coefficients]
    zs = [Z_MAX * mp.mpf(j) / samples for j in range(samples + 1)]
    return max(abs(weighted_error(exact, f, w, z)) for z in zs)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_trig_rs_holds_the_minimax_fit_rounded_to_doubles(name):
    f, w = FUNCTIONS[name]
    # C's weight vanishes at z = 0, where C's error does not matter: fit from just above.
    lo = mp.mpf(0) if name == "S" else Z_MAX * mp.mpf("1e-4")
    fitted = [float(c) for c in remez(f, w, lo, Z_MAX)]
    written = coefficients_in_trig_rs(name)
    for k, (a, b) in enumerate(zip(written, fitted)):
        assert a == b, f"{name}[{k}] = {a!r}, the fit gives {b!r}"


@pytest.mark.parametrize("name, bound", [("S", 2.0**-56.5), ("C", 2.0**-59.5)])
def test_the_polynomials_err_by_a_small_fraction_of_an_ulp(name, bound):
    """Relative to sin r or cos r: an ulp is at least 2⁻⁵³ of the value, so these errors
    are below 0.03 and 0.004 ulp; the rounding of the evaluation comes on top."""
    f, w = FUNCTIONS[name]
    error = worst_relative_error(coefficients_in_trig_rs(name), f, w)
    assert error <= bound, f"{name}: 2^{float(mp.log(error, 2)):.2f}"
