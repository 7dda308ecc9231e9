"""Rising smoke by stable fluids (Stam 1999), numpy only (docs/EXTENSIONS.md E.22).

State on a periodic grid of ``N³`` cells of size ``h = 1/N`` (the unit cube; arrays indexed ``[z, y, x]`` as a
``.vol`` grid, :mod:`a5mi.converters.volgrid`), every field at the cell centres: velocity ``u = (ux, uy, uz)``
(domain lengths per second), smoke density ``ρ`` and temperature ``θ``. One step of ``Δt``:

1. **sources**: inside the ball of radius ``r_s`` around the source point ``ρ ← max(ρ, 1)``, ``θ ← max(θ, 1)``
   and ``uy ← max(uy, u_s)``; a seeded random horizontal velocity of amplitude ``a`` perturbs the ball
   (the only randomness: the run is a function of the seed);
2. **forces**: buoyancy ``uy += Δt (β θ − α ρ)`` and vorticity confinement (Fedkiw, Stam, Jensen 2001)
   ``u += Δt ε h (n × ω)``, ``ω = ∇ × u``, ``n = ∇|ω| / |∇|ω||``;
3. **advection**: the velocity semi-Lagrangian (unconditionally stable), ``u(x) ← ũ(x_d)`` at the departure
   point ``x_d = x − Δt u(x − ½Δt u(x))`` (midpoint rule), ``ũ`` the periodic trilinear interpolant of the cell
   values; the densities ``ρ``, ``θ`` forward (:func:`carry`): each cell's content moves to its arrival point
   ``x + Δt u(x + ½Δt u(x))`` and is shared among the 8 cells around it with the trilinear weights;
4. **projection**: ``u ← u − G p`` with ``D G p = D u``, ``D`` and ``G`` the central differences
   ``(q[i+1] − q[i−1]) / 2h``. On the periodic grid both are diagonal in Fourier space, ``D̂ = Ĝ = i g``,
   ``g_a = sin(2π k_a / N) / h``, so ``û ← û − g (g·û) / |g|²`` (modes with ``g = 0`` kept) makes the discrete
   divergence ``D u`` vanish to rounding; the mean velocity (the ``k = 0`` mode) is set to 0: the mean
   buoyancy is carried by the hydrostatic pressure, not by a drift of the whole box;
5. **outflow**: ``ρ`` and ``θ`` are multiplied by ``s(y) = min(1, (1 − y)/w)`` near the top (``w`` the sink
   width), so smoke that leaves the top does not re-enter at the bottom of the periodic box; temperature
   cools by ``θ ← θ e^{−c Δt}``.

The forward transport conserves ``Σ ρ`` to rounding in any flow (the weights of each source cell sum to 1);
the backward (semi-Lagrangian) one only for a uniform velocity: in a deforming divergence-free flow its weights
do not sum to 1 per source cell and ``Σ ρ`` drifts by up to 8 % over 24 steps at CFL 1
(``tests/simulate/test_simulate.py``), which is why the smoke is carried forward.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: The file name pattern of the frames (printf style, as ``Volume { grid "smoke_%03d.vol" }`` names them).
PATTERN = "smoke_%03d.vol"


@dataclass(frozen=True)
class SmokeParams:
    """The constants of the module docstring (lengths in domain units, times in seconds)."""

    size: int = 48
    seed: int = 0
    dt: float = 1.0 / 24.0
    buoyancy: float = 1.5          # β
    weight: float = 0.05           # α
    cooling: float = 0.4           # c
    vorticity: float = 2.0         # ε
    source: tuple[float, float, float] = (0.5, 0.12, 0.5)   # x, y, z
    source_radius: float = 0.08    # r_s
    source_speed: float = 0.3      # u_s
    perturbation: float = 0.15     # a
    sink_width: float = 0.15       # w

    def __post_init__(self) -> None:
        if not 8 <= self.size <= 256:
            raise ValueError(f"the grid size must be between 8 and 256, got {self.size}")
        if not self.dt > 0.0:
            raise ValueError(f"the time step must be positive, got {self.dt}")


@dataclass
class SmokeState:
    """Velocity ``u`` (3, N, N, N: components x, y, z), density ``rho`` and temperature ``theta`` (N, N, N)."""

    u: np.ndarray
    rho: np.ndarray
    theta: np.ndarray
    rng: np.random.Generator = field(repr=False)


def initial_state(params: SmokeParams) -> SmokeState:
    """Still air, no smoke; the random stream of ``params.seed``."""
    n = params.size
    return SmokeState(np.zeros((3, n, n, n)), np.zeros((n, n, n)), np.zeros((n, n, n)),
                      np.random.default_rng(params.seed))


# ------------------------------------------------------------------------------------------------ operators
def _d(q: np.ndarray, axis: int, h: float) -> np.ndarray:
    """Central difference ``(q[i+1] − q[i−1]) / 2h`` along array ``axis`` (periodic)."""
    return (np.roll(q, -1, axis) - np.roll(q, 1, axis)) / (2.0 * h)


#: Array axis of each velocity component (x, y, z) in ``[z, y, x]`` arrays.
AXIS = (2, 1, 0)


def divergence(u: np.ndarray, h: float) -> np.ndarray:
    """``D u = Σ_a (u_a[i+e_a] − u_a[i−e_a]) / 2h``: the discrete divergence the projection removes."""
    return sum(_d(u[a], AXIS[a], h) for a in range(3))  # type: ignore[return-value]


def curl(u: np.ndarray, h: float) -> np.ndarray:
    """``ω = ∇ × u`` with central differences (3, N, N, N)."""
    dx, dy, dz = (lambda q, a=a: _d(q, AXIS[a], h) for a in range(3))
    return np.stack([dy(u[2]) - dz(u[1]), dz(u[0]) - dx(u[2]), dx(u[1]) - dy(u[0])])


def project(u: np.ndarray, h: float) -> np.ndarray:
    """The divergence-free part of ``u`` (module docstring, step 4), mean velocity removed."""
    n = u.shape[1]
    g1 = np.sin(2.0 * np.pi * np.fft.fftfreq(n, d=1.0 / n) / n) / h
    g = [g1[None, None, :], g1[None, :, None], g1[:, None, None]]  # x, y, z along the [z, y, x] axes
    hat = [np.fft.fftn(u[a]) for a in range(3)]
    gg = g[0] ** 2 + g[1] ** 2 + g[2] ** 2
    dot = g[0] * hat[0] + g[1] * hat[1] + g[2] * hat[2]
    scale = np.divide(dot, gg, out=np.zeros_like(dot), where=gg > 0.0)
    out = np.empty_like(u)
    for a in range(3):
        hat[a] = hat[a] - g[a] * scale
        hat[a][0, 0, 0] = 0.0
        out[a] = np.fft.ifftn(hat[a]).real
    return out


Stencil = tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]


def _stencil(pos: list[np.ndarray], n: int) -> Stencil:
    """The trilinear stencil (lower corner, upper corner, fraction per axis x, y, z) of positions in cells."""
    base = [np.floor(p) for p in pos]
    i0 = [b.astype(np.int64) % n for b in base]
    return i0, [(i + 1) % n for i in i0], [p - b for p, b in zip(pos, base, strict=True)]


def sample(q: np.ndarray, stencil: Stencil) -> np.ndarray:
    """``q̃`` at the stencil's positions: periodic trilinear interpolation of the cell values."""
    out = np.zeros(stencil[2][0].shape)
    for w, (iz, iy, ix) in _corners(stencil):
        out += w * q[iz, iy, ix]
    return out


def _corners(stencil: Stencil) -> Iterator[tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """The 8 cells around each stencil position with their trilinear weights ``w_z w_y w_x`` (summing to 1):
    ``(weight, (iz, iy, ix))``."""
    i0, i1, frac = stencil
    for cz in (0, 1):
        wz, iz = (frac[2], i1[2]) if cz else (1.0 - frac[2], i0[2])
        for cy in (0, 1):
            wy, iy = (frac[1], i1[1]) if cy else (1.0 - frac[1], i0[1])
            for cx in (0, 1):
                wx, ix = (frac[0], i1[0]) if cx else (1.0 - frac[0], i0[0])
                yield wz * wy * wx, (iz, iy, ix)


def _cells(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cell centres of an ``n^3`` grid in cell units, ``(x, y, z)``, each indexed ``[z, y, x]``."""
    idx = np.arange(n, dtype=np.float64)
    zz, yy, xx = np.meshgrid(idx, idx, idx, indexing="ij")
    return xx, yy, zz


def backtrace(u: np.ndarray, dt: float, h: float) -> Stencil:
    """The stencil of the departure points ``x − Δt u(x − ½Δt u(x))`` of the cell centres (the midpoint rule,
    second order in ``Δt``: a rotating blob's path stays on its circle)."""
    n = u.shape[1]
    cells = _cells(n)
    mid = _stencil([cells[a] - 0.5 * dt * u[a] / h for a in range(3)], n)
    return _stencil([cells[a] - dt * sample(u[a], mid) / h for a in range(3)], n)


def carry(q: np.ndarray, u: np.ndarray, dt: float, h: float) -> np.ndarray:
    """Forward (mass-conserving) advection of a density: each cell's content moves to its arrival point
    ``x + Δt u(x + ½Δt u(x))`` and is shared among the 8 cells around it with the trilinear weights, which sum
    to 1, so ``Σ q`` is kept to rounding whatever the flow (step 3 for ``ρ`` and ``θ``)."""
    n = q.shape[0]
    cells = _cells(n)
    mid = _stencil([cells[a] + 0.5 * dt * u[a] / h for a in range(3)], n)
    arrival = _stencil([cells[a] + dt * sample(u[a], mid) / h for a in range(3)], n)
    out = np.zeros(n ** 3)
    for w, (iz, iy, ix) in _corners(arrival):
        out += np.bincount(((iz * n + iy) * n + ix).ravel(), (w * q).ravel(), n ** 3)
    return out.reshape(q.shape)


def advect(q: np.ndarray, u: np.ndarray, dt: float, h: float) -> np.ndarray:
    """``q(x − Δt u(…))`` (step 3, :func:`backtrace`), periodic trilinear interpolation of the cell values."""
    return sample(q, backtrace(u, dt, h))


# -------------------------------------------------------------------------------------------------- a step
def _centres(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    c = (np.arange(n) + 0.5) / n
    zz, yy, xx = np.meshgrid(c, c, c, indexing="ij")
    return xx, yy, zz


def step(state: SmokeState, params: SmokeParams) -> SmokeState:
    """One step of the module docstring (1-5)."""
    n, dt = params.size, params.dt
    h = 1.0 / n
    xx, yy, zz = _centres(n)
    sx, sy, sz = params.source
    ball = (xx - sx) ** 2 + (yy - sy) ** 2 + (zz - sz) ** 2 <= params.source_radius ** 2
    u, rho, theta = state.u.copy(), np.maximum(state.rho, ball * 1.0), np.maximum(state.theta, ball * 1.0)
    kick = state.rng.normal(size=2) * params.perturbation
    u[1] = np.where(ball, np.maximum(u[1], params.source_speed), u[1])
    u[0] = np.where(ball, u[0] + kick[0], u[0])
    u[2] = np.where(ball, u[2] + kick[1], u[2])
    u[1] += dt * (params.buoyancy * theta - params.weight * rho)
    if params.vorticity > 0.0:
        w = curl(u, h)
        mag = np.sqrt((w ** 2).sum(axis=0))
        grad = np.stack([_d(mag, AXIS[a], h) for a in range(3)])
        norm = np.sqrt((grad ** 2).sum(axis=0)) + 1e-12
        nx, ny, nz = grad / norm
        force = np.stack([ny * w[2] - nz * w[1], nz * w[0] - nx * w[2], nx * w[1] - ny * w[0]])
        u += dt * params.vorticity * h * force
    back = backtrace(u, dt, h)  # one departure point per cell for the three velocity components
    rho, theta = carry(rho, u, dt, h), carry(theta, u, dt, h)
    u = np.stack([sample(u[a], back) for a in range(3)])
    u = project(u, h)
    sink = np.clip((1.0 - yy) / params.sink_width, 0.0, 1.0)
    return SmokeState(u, np.maximum(rho * sink, 0.0), np.maximum(theta * sink * math.exp(-params.cooling * dt),
                                                                     0.0), state.rng)


def run(params: SmokeParams, frames: int) -> Iterator[np.ndarray]:
    """The density ``ρ`` (N, N, N; float32, ``[z, y, x]``) after each of ``frames`` steps."""
    state = initial_state(params)
    for _ in range(frames):
        state = step(state, params)
        yield state.rho.astype(np.float32)


def check_frames(folder: str | os.PathLike[str], frames: int) -> None:
    """Raise :class:`a5mi.platform.errors.ImageWriteError` when a frame name ``folder/smoke_{f:03d}.vol`` (``f <
    frames``)
    exists and is not a ``.vol`` grid (a regular file starting with ``VOL`` version 3): a file this command did
    not write is never replaced. Only the first 4 bytes are read (opened non-blocking: a FIFO never waits)."""
    import stat

    from a5mi.platform.errors import ImageWriteError
    from a5mi.platform.paths import file_kind

    out = Path(folder)
    for f in range(frames):
        p = out / (PATTERN % f)
        if not os.path.lexists(p):
            continue
        why = f"is a {file_kind(p)}"
        if not p.is_symlink():
            try:
                fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)
                try:
                    head = os.read(fd, 4) if stat.S_ISREG(os.fstat(fd).st_mode) else b""
                finally:
                    os.close(fd)
            except OSError as exc:
                raise ImageWriteError(f"-o '{folder}': '{p}' exists and cannot be read: "
                                      f"{exc.strerror or exc}") from None
            if head == b"VOL\x03":
                continue
            if head:
                why = "is not a .vol grid"
        else:
            why = "is a symbolic link"
        raise ImageWriteError(f"-o '{folder}': '{p}' exists and {why}: not overwritten (remove it or choose "
                              "another folder)")


def write_frames(folder: str | os.PathLike[str], params: SmokeParams, frames: int,
                 progress: object = None) -> list[Path]:
    """Run :func:`run` and write frame ``f`` as ``folder/smoke_{f:03d}.vol`` (one channel, :data:`PATTERN`);
    ``progress(done, total)`` after each frame. Returns the paths. Existing frames are checked first
    (:func:`check_frames`); each frame is written atomically, and a failed write (a full disk) raises
    :class:`a5mi.platform.errors.ImageWriteError` naming the frame and how many were written before it."""
    from a5mi.converters.volgrid import write_vol
    from a5mi.platform.errors import ImageWriteError

    out = Path(folder)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ImageWriteError(f"-o '{folder}': {exc.strerror or exc}") from None
    check_frames(out, frames)
    paths = []
    for f, rho in enumerate(run(params, frames)):
        p = out / (PATTERN % f)
        try:
            write_vol(p, rho[..., None])
        except OSError as exc:
            raise ImageWriteError(f"cannot write '{p}': {exc.strerror or exc} ({f} of {frames} frames "
                                  "written)") from None
        paths.append(p)
        if callable(progress):
            progress(f + 1, frames)
    return paths
