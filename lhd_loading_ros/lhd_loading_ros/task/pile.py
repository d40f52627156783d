"""Voxelized muck pile: geometry, per-voxel soil parameters, cutting and masses (ROS-free).

Frame {M}: origin at the toe of the pile on the floor, x into the pile, z up, y to the
left, the pile centred on y = 0. The pile is a wedge of height h_pile and width w_pile
whose face rises at the slope alpha, so its depth is L = h_pile / tan(alpha). Its bounding
box is divided into n_x * n_y * n_z voxels. Every voxel carries its own soil parameters.
The material in the column (j, i) (slice j across the width, position i along x) fills
it from the floor up to ``top[j, i]``; voxel k of that column holds the part of the
material between k*dz and (k+1)*dz, so voxel fills are always in [0, 1].
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SoilRanges:
    density: tuple[float, float]
    phi: tuple[float, float]  # rad
    delta: tuple[float, float]  # rad
    cohesion: tuple[float, float]
    adhesion: float
    surcharge: tuple[float, float]
    rock_density: float
    rock_phi: float
    rock_delta: float
    rock_size: tuple[float, float]
    rocks: tuple[int, int]

    @classmethod
    def from_config(cls, cfg: dict) -> "SoilRanges":
        p = cfg["pile"]
        r = math.radians
        return cls(
            density=(p["density_min"], p["density_max"]), phi=(r(p["phi_min_deg"]), r(p["phi_max_deg"])),
            delta=(r(p["delta_min_deg"]), r(p["delta_max_deg"])), cohesion=(p["cohesion_min"], p["cohesion_max"]),
            adhesion=p["adhesion"], surcharge=(p["surcharge_min"], p["surcharge_max"]),
            rock_density=p["rock_density"], rock_phi=r(p["rock_phi_deg"]), rock_delta=r(p["rock_delta_deg"]),
            rock_size=(p["rock_size_min"], p["rock_size_max"]), rocks=(p["rocks_min"], p["rocks_max"]),
        )


def pile_depth(alpha: float, h_pile: float) -> float:
    """Horizontal depth of the wedge: L = h / tan(alpha)."""
    return h_pile / math.tan(alpha)


def wedge_mass_until(x: float, alpha: float, w: float, density: float, h_pile: float) -> float:
    """Mass of an intact homogeneous wedge between the toe and x (closed form, for checks)."""
    L = pile_depth(alpha, h_pile)
    x = min(max(x, 0.0), L)
    return density * w * math.tan(alpha) * x * x / 2.0


class VoxelPile:
    """A muck pile made of voxels. Create with :meth:`generate`."""

    def __init__(self, alpha: float, h_pile: float, w_pile: float, n_x: int, n_y: int, n_z: int,
                 density: np.ndarray, phi: np.ndarray, delta: np.ndarray, cohesion: np.ndarray,
                 adhesion: float, surcharge: float, nonhomogeneous: bool = False):
        self.alpha = float(alpha)
        self.h = float(h_pile)
        self.w = float(w_pile)
        self.n_x, self.n_y, self.n_z = int(n_x), int(n_y), int(n_z)
        self.L = pile_depth(alpha, h_pile)
        self.dx = self.L / n_x
        self.dy = self.w / n_y
        self.dz = self.h / n_z
        self.inv_dz = 1.0 / self.dz
        shape = (n_y, n_x, n_z)
        for name, arr in (("density", density), ("phi", phi), ("delta", delta), ("cohesion", cohesion)):
            if np.shape(arr) != shape:
                raise ValueError(f"{name} must have shape {shape} (n_y, n_x, n_z), got {np.shape(arr)}")
        self.density = np.asarray(density, dtype=float)
        self.phi = np.asarray(phi, dtype=float)
        self.delta = np.asarray(delta, dtype=float)
        self.cohesion = np.asarray(cohesion, dtype=float)
        self.adhesion = float(adhesion)
        self.surcharge = float(surcharge)
        self.nonhomogeneous = bool(nonhomogeneous)
        self.x_centers = (np.arange(n_x) + 0.5) * self.dx
        self.y_centers = -self.w / 2 + (np.arange(n_y) + 0.5) * self.dy
        self.z_edges = np.arange(n_z + 1) * self.dz
        # Intact surface at each column centre.
        self.top0 = np.tile(np.clip(self.x_centers * math.tan(alpha), 0.0, self.h), (n_y, 1))
        self.top = self.top0.copy()
        self.klass = np.zeros(shape, dtype=np.int8)  # 0 gravel, 1 rock
        self.rocks = 0
        self._update_mass_tables()
        self.removed_mass = 0.0

    def _update_mass_tables(self) -> None:
        # mass of each full voxel, and the mass of each column below each voxel edge
        self._voxel_mass = self.density * (self.dx * self.dy * self.dz)
        self._cum = np.concatenate([np.zeros((self.n_y, self.n_x, 1)), np.cumsum(self._voxel_mass, axis=2)], axis=2)

    # ---------------------------------------------------------------- generation
    @classmethod
    def generate(cls, rng: np.random.Generator, alpha: float, h_pile: float, w_pile: float,
                 n_x: int, n_y: int, n_z: int, soil: SoilRanges, nonhomogeneous: bool = False,
                 voxel_spread: float = 0.05) -> "VoxelPile":
        """A new pile: one gravel parameter set drawn from the ranges; each voxel's density and
        cohesion vary by +-voxel_spread (relative) around it; if nonhomogeneous, rocks of
        rock_size are placed inside the wedge (the voxels whose centres fall in a rock take the
        rock parameters). Friction angles are per material class (gravel, rock): the FEE's
        failure-angle search is then shared by all voxels of a class.

        A cohesionless face stands at most at its friction angle (a dumped pile at its angle of
        repose), so the pile's friction angle is drawn from [max(phi_min, alpha), phi_max]: a 35 deg
        pile of 34-37 deg gravel is of 35-37 deg gravel, a 40 deg pile is of a material that stands
        at 40 deg (docs/modeling.md "Piles steeper than gravel"). Below phi_min nothing changes. A
        slope above phi_max is refused: no pile of that material stands so steep."""
        shape = (n_y, n_x, n_z)
        phi_lo, phi_hi = soil.phi
        if not alpha <= phi_hi + 1e-9:
            raise ValueError(
                f"a pile of {math.degrees(alpha):.1f} deg is steeper than its material's largest friction angle "
                f"({math.degrees(phi_hi):.1f} deg): a cohesionless face stands at most at its friction angle. "
                "Expected a slope up to that angle, or a material that stands steeper "
                "(pile.phi_max_deg, randomization.phi_max_deg)")
        base_rho = rng.uniform(*soil.density)
        base_phi = rng.uniform(max(phi_lo, alpha), phi_hi)
        base_delta = rng.uniform(*soil.delta)
        base_c = rng.uniform(*soil.cohesion)
        q = rng.uniform(*soil.surcharge)
        jitter = lambda: 1.0 + rng.uniform(-voxel_spread, voxel_spread, size=shape)  # noqa: E731
        density = base_rho * jitter()
        phi = np.full(shape, base_phi)
        delta = np.full(shape, min(base_delta, base_phi))
        cohesion = base_c * jitter()
        pile = cls(alpha, h_pile, w_pile, n_x, n_y, n_z, density, phi, delta, cohesion,
                   soil.adhesion, q, nonhomogeneous=nonhomogeneous)
        if nonhomogeneous:
            pile._place_rocks(rng, soil)
        return pile

    def roughen(self, rng: np.random.Generator, sd: float, corr: float) -> None:
        """Give the intact surface a random relief: a Gaussian random field of standard deviation
        `sd` (m) and correlation length `corr` (m) over the columns (both axes), added to the plane
        and clipped to [0, h]: the bumps and hollows of a pile dumped by hand or by a recirculating
        feeder, which a plane fit (the LiDAR slope node) averages out. Only the surface moves: the
        voxels below the new surface fill, the zones (x_min, x_max from the intact pile's mass)
        follow the new profile. The field is white noise smoothed by a Gaussian kernel of standard
        deviation corr / 2 along each axis (correlation falls to exp(-1/2) at a distance corr / sqrt 2
        ... exp(-1) at corr), then scaled to `sd` over the columns."""
        if not (math.isfinite(sd) and sd >= 0.0 and math.isfinite(corr) and corr > 0.0):
            raise ValueError(f"surface relief needs sd >= 0 and corr > 0 (m), got sd={sd!r}, corr={corr!r}")
        if sd == 0.0:
            return
        noise = rng.standard_normal((self.n_y, self.n_x))
        for axis, step in ((1, self.dx), (0, self.dy)):
            s_cells = 0.5 * corr / step
            half = max(1, int(math.ceil(3.0 * s_cells)))
            k = np.exp(-0.5 * (np.arange(-half, half + 1) / max(s_cells, 1e-9)) ** 2)
            k /= k.sum()
            pad = [(0, 0), (0, 0)]
            pad[axis] = (half, half)
            padded = np.pad(noise, pad, mode="reflect" if noise.shape[axis] > half else "wrap")
            noise = np.apply_along_axis(lambda v: np.convolve(v, k, mode="valid"), axis, padded)
        noise *= sd / max(float(noise.std()), 1e-12)
        self.top0 = np.clip(self.top0 + noise, 0.0, self.h)
        self.top = self.top0.copy()

    def slice_slope(self, y: float = 0.0, margin: float = 0.03) -> float:
        """The face's slope (rad) as one scan line at y sees it: the least-squares line through the
        intact column tops of the slice nearest y that lie between `margin` above the floor and
        `margin` below the crest. On a plane face it is alpha; on a rough one (roughen) it is the
        slope the machine's LiDAR, scanning the pile's XZ plane, can measure at best
        (docs/perception.md "Rough faces": 0.3-1.9 deg from alpha on average for 3 cm of relief)."""
        j = int(np.argmin(np.abs(self.y_centers - y)))
        top = self.top0[j]
        face = (top > margin) & (top < self.h - margin)
        if face.sum() < 2:
            return self.alpha
        return math.atan(float(np.polyfit(self.x_centers[face], top[face], 1)[0]))

    def _place_rocks(self, rng: np.random.Generator, soil: SoilRanges) -> None:
        n = int(rng.integers(soil.rocks[0], soil.rocks[1] + 1))
        xc, yc, zc = self.x_centers, self.y_centers, (self.z_edges[:-1] + self.z_edges[1:]) / 2
        placed = 0
        for _ in range(20 * max(n, 1)):
            if placed >= n:
                break
            size = rng.uniform(*soil.rock_size)
            x = rng.uniform(size / 2, self.L - size / 2)
            zmax = min(x * math.tan(self.alpha), self.h) - size / 2
            if zmax <= size / 2:
                continue
            z = rng.uniform(size / 2, zmax)
            y = rng.uniform(-self.w / 2 + size / 2, self.w / 2 - size / 2) if self.w > size else 0.0
            # the voxels (n_y, n_x, n_z) whose centres lie in the rock: the grid is separable
            inside = ((np.abs(yc - y) <= size / 2)[:, None, None] & (np.abs(xc - x) <= size / 2)[None, :, None]
                      & (np.abs(zc - z) <= size / 2)[None, None, :])
            if not inside.any():  # rock smaller than a voxel: take the voxel holding its centre
                inside = np.zeros_like(inside)
                j = min(int((y + self.w / 2) / self.dy), self.n_y - 1)
                i = min(int(x / self.dx), self.n_x - 1)
                k = min(int(z / self.dz), self.n_z - 1)
                inside[j, i, k] = True
            self.density[inside] = soil.rock_density
            self.phi[inside] = soil.rock_phi
            self.delta[inside] = soil.rock_delta
            self.klass[inside] = 1
            placed += 1
        self._update_mass_tables()
        self.rocks = placed

    # ---------------------------------------------------------------- queries
    def column_index(self, x: float) -> int:
        """Index i of the column holding x, or -1 outside [0, L)."""
        if x < 0.0 or x >= self.L:
            return -1
        return min(int(x / self.dx), self.n_x - 1)

    def slices_in(self, y_lo: float, y_hi: float) -> np.ndarray:
        """Indices j of the slices whose centre lies in [y_lo, y_hi]."""
        return np.nonzero((self.y_centers >= y_lo) & (self.y_centers <= y_hi))[0]

    def surface_height(self, x: float, j: int | None = None) -> float:
        """Current height of the pile at x (slice j, or the highest slice). 0 before the toe,
        h behind the back end (the draw point's back wall holds the material there)."""
        if x < 0.0:
            return 0.0
        if x >= self.L:
            return self.h
        i = self.column_index(x)
        return max(self.top[:, i].tolist()) if j is None else float(self.top[j, i])

    def fills(self) -> np.ndarray:
        """Fill fraction of every voxel, shape (n_y, n_x, n_z), each in [0, 1]."""
        lo = self.z_edges[:-1][None, None, :]
        return np.clip((self.top[:, :, None] - lo) / self.dz, 0.0, 1.0)

    def voxel_count(self) -> int:
        """Number of voxels holding any material."""
        return int(np.count_nonzero(self.fills() > 0.0))

    def mass_below(self, j: np.ndarray, i: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Mass of the material of columns (j, i) between the floor and height z (vectorised)."""
        z = np.clip(np.asarray(z, dtype=float), 0.0, self.h)
        k = np.minimum((z / self.dz).astype(np.intp), self.n_z - 1)
        return self._cum[j, i, k] + (z - k * self.dz) / self.dz * self._voxel_mass[j, i, k]

    def total_mass(self) -> float:
        return float(np.sum(self.fills() * self._voxel_mass))

    def cumulative_mass_x(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, mass of the intact pile between the toe and x) at the column edges."""
        col = np.sum(self.mass_below(*np.meshgrid(np.arange(self.n_y), np.arange(self.n_x), indexing="ij"),
                                     self.top0), axis=0)
        edges = np.arange(self.n_x + 1) * self.dx
        return edges, np.concatenate([[0.0], np.cumsum(col)])

    def x_at_mass(self, m: float) -> float:
        """Smallest x such that the intact pile holds mass m between the toe and x.
        Clipped to L if the pile holds less than m."""
        return self.x_at_masses((m,))[0]

    def x_at_masses(self, ms) -> list[float]:
        """x_at_mass for each of ms, the pile's mass profile computed once."""
        edges, cum = self.cumulative_mass_x()
        return [self.L if m >= cum[-1] else float(np.interp(m, cum, edges)) for m in ms]

    def soil_at(self, j: np.ndarray, i: int, z: np.ndarray):
        """(density, phi, delta, cohesion) of the voxels of slices j in column i at heights z."""
        k = np.clip((np.asarray(z) / self.dz).astype(int), 0, self.n_z - 1)
        return self.density[j, i, k], self.phi[j, i, k], self.delta[j, i, k], self.cohesion[j, i, k]

    # ---------------------------------------------------------------- cutting
    def cut(self, x0: float, z0: float, x1: float, z1: float, j: np.ndarray) -> float:
        """The bucket tip moved from (x0, z0) to (x1, z1) across slices j: every column whose
        centre it passed loses the material above the tip's height there. Returns the mass
        removed (kg); the removed voxels leave the pile."""
        if x1 <= x0 or len(j) == 0:
            return 0.0
        i_lo = int(math.floor(x0 / self.dx - 0.5)) + 1  # first centre strictly after x0
        i_hi = int(math.floor(x1 / self.dx - 0.5))       # last centre at or before x1
        i_lo, i_hi = max(i_lo, 0), min(i_hi, self.n_x - 1)
        if i_hi < i_lo:
            return 0.0
        ii = np.arange(i_lo, i_hi + 1)
        zc = np.maximum(z0 + (z1 - z0) * (self.x_centers[ii] - x0) / (x1 - x0), 0.0)
        jj = j[:, None]
        iig = ii[None, :]
        old = self.top[jj, iig]
        if not np.any(old > zc):
            return 0.0
        new = np.minimum(old, zc)
        removed = self.mass_below(jj, iig, old) - self.mass_below(jj, iig, new)
        self.top[jj, iig] = new
        m = float(np.sum(removed))
        self.removed_mass += m
        return m
