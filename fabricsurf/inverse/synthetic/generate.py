"""Synthetic measurement data (docs/contracts.md format) from the continuum or the Hencky lattice.

Used by the hidden-effect demo, the diagnosis tests and the benchmark: the data are made with
a model richer than the one that will be fitted (a hidden effect), on a different discretisation
(finer mesh, or the spring lattice), plus Gaussian noise of known standard deviation.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabricsurf.inverse.contract.experiment import Experiment, template
from fabricsurf.model.slip import SLIP_STRAIN
from fabricsurf.model.terms import Term

__all__ = [
    "add_noise",
    "continuum_data",
    "correlated_field",
    "grid_points",
    "lattice_data",
    "noisy_copy",
    "rewrite_in_m_kn",
    "template",
]  # template: the experiment to fill in


def grid_points(length: float, width: float, nx: int, ny: int, margin: float = 0.05) -> np.ndarray:
    """An nx × ny grid of measurement points inside the specimen (a DIC-like point cloud)."""
    x = np.linspace(margin * length, (1 - margin) * length, nx)
    y = np.linspace(margin * width, (1 - margin) * width, ny)
    return np.array([(a, b) for a in x for b in y])


def correlated_field(
    points: np.ndarray, length: float, rng: np.random.Generator, components: int
) -> np.ndarray:
    """Zero-mean Gaussian random field of unit variance at ``points`` with the squared-
    exponential correlation exp(−|x − x'|²/(2 ℓ²)), ℓ = ``length``: the smoothing of DIC
    subsets. One independent field per component (Cholesky factor of the correlation matrix,
    a small diagonal added for the factor to exist)."""
    d2 = ((points[:, None, :] - points[None, :, :]) ** 2).sum(axis=-1)
    K = np.exp(-0.5 * d2 / length**2) + JITTER * np.eye(len(points))
    return np.linalg.cholesky(K) @ rng.normal(size=(len(points), components))


JITTER = 1e-8
"""Added to the correlation matrix's diagonal (its factor exists for closely spaced points)."""

MAX_CORRELATED_POINTS = 8000
"""The largest point cloud per step that gets a correlated field (a dense Cholesky factor)."""


def add_noise(
    exp: Experiment,
    noise_std: float,
    force_noise_std: float,
    seed: int,
    correlation_length: float = 0.0,
) -> Experiment:
    """Gaussian noise on every displacement component and force (same draw on every rank).
    ``correlation_length`` > 0 (mm): the displacement noise is a Gaussian random field of that
    correlation length (:func:`correlated_field`), drawn independently at every step, as DIC
    subsets leave; 0: independent at every point."""
    rng = np.random.default_rng(seed)
    if correlation_length > 0 and exp.has_field:
        noise = np.zeros(exp.u.shape)
        for s in exp.steps:
            rows = exp.step_rows(s)
            if len(rows) > MAX_CORRELATED_POINTS:
                raise ValueError(
                    f"add_noise: {len(rows)} points at step {s}: a correlated "
                    f"field is drawn for at most {MAX_CORRELATED_POINTS}"
                )
            if len(rows):
                noise[rows] = noise_std * correlated_field(
                    exp.X[rows, :2], correlation_length, rng, exp.u.shape[1]
                )
        exp.u = exp.u + noise
    else:
        exp.u = exp.u + rng.normal(0.0, noise_std, exp.u.shape)
    if exp.has_force:
        exp.force = exp.force + rng.normal(0.0, force_noise_std, exp.force.shape)
        exp.force_noise_std = float(force_noise_std)
    if exp.has_field:
        exp.noise_std = float(noise_std)
    return exp


def noisy_copy(
    exp: Experiment,
    noise_std: float,
    force_noise_std: float,
    seed: int,
    correlation_length: float = 0.0,
) -> Experiment:
    """:func:`add_noise` on a copy: ``exp`` (clean data, drawn on again) stays as it is."""
    return add_noise(replace(exp), noise_std, force_noise_std, seed, correlation_length)


def continuum_data(
    exp: Experiment, model: list[Term], h: float, comm: MPI.Comm = MPI.COMM_WORLD
) -> Experiment:
    """Fill ``exp`` with the continuum solution of ``model`` on a mesh of size ``h``."""
    from fabricsurf.experiments import get_test
    from fabricsurf.inverse.forward.runs import ForwardModel

    exp.u = np.zeros((len(exp.field_step), get_test(exp.test).d))
    with ForwardModel(exp, model, h=h, comm=comm) as fm:
        pred = fm.run()
    if not np.isfinite(pred.u).all():
        raise RuntimeError("synthetic data: a measurement point lies outside the mesh")
    exp.u = pred.u.copy()
    if exp.has_force:
        exp.force = pred.force.copy()
    return exp


def lattice_data(
    exp: Experiment,
    spacing: float,
    k_l: float,
    k_s: float,
    A_g: float,
    every: int = 1,
    k4: float = 0.0,
    k6: float = 0.0,
    tau_f: float = 0.0,
    T_s: float = 0.0,
    eps_s: float = SLIP_STRAIN,
    c_st: float = 0.0,
    k_x: float = 0.0,
    s_comp: float = 0.0,
) -> Experiment:
    """Replace ``exp`` by the Hencky lattice's response (Barchiesi et al. 2020 clamps: two held
    layers).

    The lattice spacing is ``hencky.spanning_spacing`` of ``spacing`` (the nearest for which the
    held layers sit on both ends of the specimen: the grips are where the experiment says). The
    measurement points are the lattice nodes (every ``every``-th, clamp/grip layers excluded);
    continuum moduli map to lattice stiffnesses by ``lattice_from_continuum`` (``k4``, ``k6``:
    the ``shear_locking`` moduli, ``tau_f``: the ``crossover_friction`` modulus, nonlinear
    shear springs at the crossings, ``T_s`` and ``eps_s``: the ``yarn_slip`` tension and slip
    strain, fibre springs that slide past their slip force; effects no named term has, from
    ``network.couplings``: ``c_st`` the shear-tension coupling, shear stiffness
    k_s(1 + c_st((λ−1)+(μ−1))), ``k_x`` (N/mm) the crimp interchange k_x(λ−1)(μ−1), ``s_comp``
    the fibres' compression softness, stiffness (1 − s_comp)k_l for λ < 1; all 0 by default).
    """
    from fabricsurf.network import hencky
    from fabricsurf.network.hencky_moduli import lattice_from_continuum

    angles = tuple(exp.fibre_angles_deg)
    spacing = hencky.spanning_spacing(exp.length, spacing, angles)
    k = lattice_from_continuum(
        k_l,
        k_s,
        A_g,
        spacing,
        angles,
        k4=k4,
        k6=k6,
        tau_f=tau_f,
        T_s=T_s,
        eps_s=eps_s,
        c_st=c_st,
        k_x=k_x,
        s_comp=s_comp,
    )
    lat = hencky.hencky_lattice(exp.length, exp.width, spacing, angles, **k)
    X = lat.net.X
    span = (float(X[:, 0].min()), float(X[:, 0].max()))
    if not np.allclose(span, (0.0, exp.length), atol=1e-6 * exp.length):
        raise ValueError(
            f"lattice_data: at fibre angles {angles} deg the lattice spans x = "
            f"{span[0]:.4g}..{span[1]:.4g} mm, not the specimen's 0..{exp.length:g}"
            " mm (its grip layer would not sit on the specimen's end)"
        )
    held = np.zeros(len(X), bool)
    held[np.concatenate([lat.clamp, lat.grip])] = True
    nodes = np.flatnonzero(~held)[::every]
    states = _path_states(lat, np.asarray(exp.path, float))
    u = [(states[float(d)].x - X)[nodes] for d in exp.path]
    force = [states[float(d)].reactions["grip"][0] for d in exp.path]
    steps = exp.steps
    exp.field_step = np.repeat(steps, len(nodes))
    exp.X, exp.u = np.tile(X[nodes], (len(steps), 1)), np.vstack(u)
    exp.force = np.array(force)
    return exp


def _path_states(lat, path: np.ndarray) -> dict:
    """The lattice's equilibrium at every grip displacement of ``path`` ({d: StepResult}): one
    continuation per sign of d, landing on each |d| in turn (the lattice's energy has no
    history, so a state does not depend on the path to it), at least four steps to the
    largest and one per displacement on the way."""
    from fabricsurf.network.equilibrium import solve_steps

    out = {}
    for sign in (1.0, -1.0):
        ds = np.unique(path[sign * path > 0])
        if not len(ds):
            continue
        end = ds[np.argmax(np.abs(ds))]
        res = solve_steps(
            lat.net,
            lat.bias_bcs(float(end)),
            n_steps=4,
            stops=ds / end,
            reaction_sets={"grip": lat.grip},
        )
        for d in ds:
            out[float(d)] = min(res, key=lambda r: abs(r.t * end - d))
    if np.any(path == 0):
        out[0.0] = solve_steps(lat.net, lat.bias_bcs(0.0), 1, reaction_sets={"grip": lat.grip})[-1]
    return out


def rewrite_in_m_kn(directory: str | Path) -> None:
    """Rewrite a measurement directory written in mm and N (:func:`~.data.write_experiment`) in
    m and kN: the numbers change, not the data (a user's units, for the loader to convert)."""
    directory = Path(directory)
    toml = directory / "experiment.toml"
    text = (
        toml.read_text()
        .replace('length = "mm"', 'length = "m"')
        .replace('force = "N"', 'force = "kN"')
    )
    lines = []
    for line in text.splitlines():
        key = line.split("=")[0].strip()
        if key in ("length", "width", "noise_std", "force_noise_std") and '"' not in line:
            line = f"{key} = {float(line.split('=')[1]) / 1000.0!r}"
        lines.append(line)
    toml.write_text("\n".join(lines) + "\n")
    for name in ("field.csv", "force.csv"):
        if not (directory / name).exists():
            continue
        rows = (directory / name).read_text().splitlines()
        out = [rows[0]]
        for r in rows[1:]:
            v = [float(x) for x in r.split(",")]
            out.append(",".join([str(int(v[0]))] + [repr(a * 1e-3) for a in v[1:]]))
        (directory / name).write_text("\n".join(out) + "\n")
