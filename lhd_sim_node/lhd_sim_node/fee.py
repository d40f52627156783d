"""Extended Fundamental Earth-moving Equation (FEE) on sloped ground.

Luengo, Singh & Cannon (1998), as used by Salas et al. for the LHD bucket:

    F = w (d^2 gamma g N_gamma + c d N_c + q d N_q + c_a d N_a)

    D       = cos(rho + delta) + sin(rho + delta) cot(beta + phi)
    N_gamma = (cot beta - tan alpha)(cos alpha + sin alpha cot(beta + phi)) / (2 D)
    N_c     = (1 + cot beta cot(beta + phi)) / D
    N_q     = (cot beta - tan alpha)(cos alpha + sin alpha cot(beta + phi)) / D
    N_a     = (1 - cot rho cot(beta + phi)) / D

N_q differs from the transcription in DESIGN.md, which drops the factor (cot beta - tan alpha):
the surcharge acts on the wedge's top surface, whose length scales with that factor just as
the wedge's weight does (N_q = 2 N_gamma, as in Luengo et al.). Without it, at alpha = 0 the
surcharge would act on a length d instead of d cot(beta); ``test_fee.py`` solves the wedge's
force balance directly and only the corrected N_q satisfies it.

rho: tool rake angle, delta: soil-tool friction, phi: internal friction,
alpha: slope of the soil surface ahead of the tool, beta: failure-plane angle,
d: tool depth below the surface, w: tool width, gamma: density [kg/m^3],
c: cohesion [Pa], c_a: adhesion [Pa], q: surcharge [Pa].

beta is not a soil property: the soil fails along the plane that needs the least
force (Coulomb's passive wedge), so beta is found by minimising F over the range
in which the wedge exists (cot beta > tan alpha and D > 0).

At alpha = 0 these factors are exactly the McKyes/Reece factors for a wedge
bounded by the vertical through the tool tip; ``test_fee.py`` checks them against
a direct static equilibrium of that wedge.

The force on the tool: horizontal component F sin(rho + delta) opposing the
motion, vertical component F cos(rho + delta) pointing down (negative = up).

All functions are vectorised over numpy arrays (broadcasting), angles in radians.
"""
from __future__ import annotations

import numpy as np

G = 9.81
_EPS = 1e-9


def n_factors(beta, alpha, rho, delta, phi):
    """Return (N_gamma, N_c, N_q, N_a, D) for the given angles (broadcast)."""
    cot_bp = 1.0 / np.tan(beta + phi)
    cot_b = 1.0 / np.tan(beta)
    s = rho + delta
    D = np.cos(s) + np.sin(s) * cot_bp
    slope_term = np.cos(alpha) + np.sin(alpha) * cot_bp
    n_gamma = (cot_b - np.tan(alpha)) * slope_term / (2.0 * D)
    n_c = (1.0 + cot_b * cot_bp) / D
    n_q = (cot_b - np.tan(alpha)) * slope_term / D
    n_a = (1.0 - (1.0 / np.tan(rho)) * cot_bp) / D
    return n_gamma, n_c, n_q, n_a, D


def fee_force(beta, d, w, gamma, c, q, c_a, alpha, rho, delta, phi):
    """FEE magnitude F [N] for a given failure angle beta (no minimisation)."""
    n_gamma, n_c, n_q, n_a, _ = n_factors(beta, alpha, rho, delta, phi)
    return w * (d * d * gamma * G * n_gamma + c * d * n_c + q * d * n_q + c_a * d * n_a)


# Failure-angle grid: 1..89 degrees. 128 points give a minimum within 0.2 % of a
# golden-section search over the same range (test_fee checks this).
BETA_GRID = np.radians(np.linspace(1.0, 89.0, 128))


def fee_min(d, w, gamma, c, q, c_a, alpha, rho, delta, phi, beta_grid=BETA_GRID):
    """Minimise the FEE over the failure angle for a batch of tools.

    All arguments except ``beta_grid`` are 1-D arrays of equal length n (or
    scalars). Returns (F [n], beta* [n]). Entries with d <= 0 give F = 0.
    Wedges that cannot exist for a beta (cot beta <= tan alpha, or D <= 0) are
    excluded from the search.
    """
    d = np.atleast_1d(np.asarray(d, dtype=float))
    args = [np.atleast_1d(np.asarray(a, dtype=float))[:, None] if np.ndim(a) else a
            for a in (w, gamma, c, q, c_a, alpha, rho, delta, phi)]
    w_, gamma_, c_, q_, ca_, alpha_, rho_, delta_, phi_ = args
    dd = np.maximum(d, 0.0)[:, None]
    b = beta_grid[None, :]
    n_gamma, n_c, n_q, n_a, D = n_factors(b, alpha_, rho_, delta_, phi_)
    F = w_ * (dd * dd * gamma_ * G * n_gamma + c_ * dd * n_c + q_ * dd * n_q + ca_ * dd * n_a)
    valid = (D > _EPS) & ((1.0 / np.tan(b)) > np.tan(alpha_) + _EPS)
    F = np.where(valid, F, np.inf)
    idx = np.argmin(F, axis=1)
    rows = np.arange(F.shape[0])
    f_min = F[rows, idx]
    f_min = np.where(np.isfinite(f_min), f_min, 0.0)
    f_min = np.where(d > 0.0, np.maximum(f_min, 0.0), 0.0)
    return f_min, beta_grid[idx]


def tool_force_components(F, rho, delta):
    """Horizontal (opposing motion, >= 0 for rho+delta in (0, pi)) and vertical
    (positive = downward on the tool) components of the FEE force."""
    s = rho + delta
    return F * np.sin(s), F * np.cos(s)


_BIG = 1e12  # stands for "no wedge at this beta" in the tables (finite: 0 * _BIG stays 0)


class FeeTable:
    """Fast FEE for the simulator's inner loop.

    For one pile slope alpha and a few material classes (phi, delta), the N factors over
    the failure-angle grid depend only on the rake angle, which is quantised to
    ``rake_step`` and cached. F for a batch of slices is then a (n, 4) @ (4, n_beta)
    product and a row minimum. ``test_fee`` checks it against :func:`fee_min`.
    """

    def __init__(self, alpha: float, phis, deltas, rake_step: float = np.radians(0.25), beta_grid=BETA_GRID):
        self.alpha = float(alpha)
        self.phis = [float(p) for p in phis]
        self.deltas = [float(d) for d in deltas]
        self.rake_step = float(rake_step)
        self.beta = beta_grid
        self._cache: dict[tuple[int, int], tuple[np.ndarray, float, float]] = {}

    def grids(self, klass: int, rake: float):
        """(N [4, n_beta] rows N_gamma, N_c, N_q, N_a; sin(rake+delta); cos(rake+delta))."""
        q = int(round(rake / self.rake_step))
        key = (klass, q)
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        rk = q * self.rake_step
        phi, delta = self.phis[klass], self.deltas[klass]
        n_gamma, n_c, n_q, n_a, D = n_factors(self.beta, self.alpha, rk, delta, phi)
        valid = (D > _EPS) & ((1.0 / np.tan(self.beta)) > np.tan(self.alpha) + _EPS)
        N = np.where(valid, np.vstack([n_gamma, n_c, n_q, n_a]), _BIG)
        if not valid.any():  # no admissible wedge: no resistance from this class at this rake
            N = np.zeros_like(N)
        hit = (np.ascontiguousarray(N), float(np.sin(rk + delta)), float(np.cos(rk + delta)))
        self._cache[key] = hit
        return hit

    def force(self, klass: int, d: np.ndarray, w: float, gamma: np.ndarray, c: np.ndarray, q: float,
              c_a: float, rake: float):
        """(F [n], sin(rake+delta), cos(rake+delta)) for slices of one class with depths d > 0."""
        N, s, co = self.grids(klass, rake)
        coef = np.empty((len(d), 4))
        coef[:, 0] = w * d * d * gamma * G
        coef[:, 1] = w * c * d
        coef[:, 2] = w * q * d
        coef[:, 3] = w * c_a * d
        F = (coef @ N).min(axis=1)
        return np.maximum(F, 0.0), s, co
