"""How the bias test discretises nearly inextensible fibres, and what it tells the user
(docs/theory.md, "Locking").

A mesh whose edges do not follow the fibres locks (the grip force grows with the fibre
stiffness K); the bias plug-in therefore meshes along the fibres whenever they are at ±θ to the
load (geometry/fibre_mesh.py). Whatever is chosen is recorded (mesh kind, the size actually
used, the fibre treatment, the fibre angles as given and as used) and, when the mesh is not
the corner-to-corner lattice, its size is more than 5 % from the one asked (with why), the
fibre pair was respelled or the set-up may lock, logged on rank 0 before anything is computed
(a warning when it may lock).
"""

from __future__ import annotations

import logging
import math

from mpi4py import MPI

from fabricsurf.geometry.aligned import (
    ANGLE_TOLERANCE_DEG,
    EXACT_DEG,
    lattice_sizes,
    symmetric_angle,
)
from fabricsurf.geometry.fibre_mesh import bias_mesh
from fabricsurf.geometry.specimen import Specimen, bias_points, check_positive
from fabricsurf.log import rank0, warn
from fabricsurf.model.terms import Term

logger = logging.getLogger(__name__)

TREATMENTS = ("auto", "full", "reduced")
"""``auto`` (= ``full``) and the two of
:data:`fabricsurf.discretise.quadrature.FIBRE_TREATMENTS`."""

LOCKING_RATIO = 1e2
"""K/k_s from which fully integrated fibre terms on a mesh not aligned with the fibres give a
grip force visibly above the locking-free one (benchmarks/locking.py): a warning is logged."""

MISMATCH_LIMIT = 1.0
"""Largest K/k_s · δ² (δ in radians: an aligned lattice's angle against the fibres') without a
warning: the fibres then cross the lattice's edges and stretch under the net's shear, so the
force grows with K. Measured on 250 × 115 (benchmarks/locking.py's sizes) at ±45°: δ = 0.020°
and 0.034° give 0.3 % and 1.4 % above the limit at K/k_s·δ² = 1.2 and 3.5, and 14.5 % and 57 %
at K/k_s = 10⁹ (docs/theory.md)."""

MIN_SEPARATION_DEG = 5.0
"""Least angle between the two fibre families as lines (as the measurement contract's)."""


def fibre_stiffness(model: list[Term]) -> float:
    """K: the fibres' stiffness at small stretch, the sum of the fibre terms' (their energies
    add): k_l with ``fibre_stretch`` alone, k_l + T_s/ε_s with ``yarn_slip`` (sticking yarns)."""
    return sum(t.small_stretch_stiffness() for t in model if t.fibre)


def stiffness_ratio(model: list[Term]) -> float:
    """K/k_s: :func:`fibre_stiffness` over the sum of the other first-gradient moduli (inf
    for inextensible fibres or no other membrane term; 0 without fibre terms)."""
    fibre = [t for t in model if t.fibre]
    if not fibre:
        return 0.0
    if any(getattr(t, "inextensible", False) for t in fibre):
        return math.inf
    K = fibre_stiffness(model)
    rest = sum(sum(t.values().values()) for t in model if t.order == 1 and not t.fibre)
    return K / rest if rest > 0 else math.inf


def tolerated_mismatch_deg(model: list[Term]) -> float:
    """The largest angle (deg) between an aligned lattice and the fibres at which the model's
    K/k_s stays within :data:`MISMATCH_LIMIT` (0 for inextensible fibres, inf without fibre
    terms): ``mesh = "auto"`` takes no corner-to-corner lattice further off."""
    ratio = stiffness_ratio(model)
    return math.degrees(math.sqrt(MISMATCH_LIMIT / ratio)) if ratio > 0 else math.inf


LOCKING_FREE_MESHES = ("aligned", "lattice_pair", "zones")
"""Mesh kinds on which fully integrated fibre terms do not lock in the bias test: the
pin-jointed-net solution lies in the discrete space (geometry/aligned.py,
geometry/lattice_pair.py, geometry/zone_mesh.py)."""


EXACT_MESHES = ("aligned", "lattice_pair")
"""Mesh kinds that hold the inextensible net of the bias test exactly (the corner-line mesh
``zones`` holds only its piecewise affine idealisation)."""


def may_lock(kind: str, treatment: str, ratio: float, mismatch_deg: float = 0.0) -> bool:
    """Whether the answer may be locked (or, reduced, too soft): stiff fibres (K/k_s ≥
    :data:`LOCKING_RATIO`) on a mesh not in :data:`LOCKING_FREE_MESHES` or with reduced fibre
    terms; an aligned lattice whose angle is ``mismatch_deg`` off the fibres' with K/k_s · δ²
    above :data:`MISMATCH_LIMIT`; exact inextensibility on a mesh not in
    :data:`EXACT_MESHES`."""
    if kind == "aligned" and ratio * math.radians(mismatch_deg) ** 2 > MISMATCH_LIMIT:
        return True
    if math.isinf(ratio):
        return kind not in EXACT_MESHES or treatment == "reduced"
    return ratio >= LOCKING_RATIO and (treatment == "reduced" or kind not in LOCKING_FREE_MESHES)


def choose_fibre_treatment(
    requested: str,
    specimen,
    model: list[Term],
    h: float,
    given: tuple[float, float],
    used: tuple[float, float],
) -> dict:
    """The record of the discretisation (mesh kind, h requested and used, fibre treatment,
    fibre angles given and used, K/k_s, whether the answer may be locked) and its ``notice``
    ("" when there is nothing to say: a corner-to-corner aligned mesh, fibres as given).
    ``auto`` is ``full``: the reduced treatment is measured too soft (docs/theory.md)."""
    if requested not in TREATMENTS:
        raise ValueError(f"fibre_treatment = {requested!r} must be one of {', '.join(TREATMENTS)}")
    kind = specimen.kind
    treatment = "full" if requested == "auto" else requested
    ratio = stiffness_ratio(model)
    mismatch = float(getattr(specimen, "angle_mismatch_deg", 0.0))
    record = {
        "mesh_kind": kind,
        "h_requested": float(h),
        "h_used": float(specimen.h),
        "fibre_treatment": treatment,
        "fibre_angles_given": list(given),
        "fibre_angles_used": list(used),
        "fibre_stiffness_ratio": ratio,
        "angle_mismatch_deg": mismatch,
        "may_lock": may_lock(kind, treatment, ratio, mismatch),
    }
    record["notice"] = _notice(
        record, getattr(specimen, "note", ""), _size_reason(record, specimen, model, used)
    )
    return record


LATTICES = ("aligned", "lattice_pair", "lattice_pair_short")
"""Mesh kinds built as fibre lattices, whose h is the lattice's, not the one asked."""

SIZE_NOTE = 0.05
"""A mesh whose size differs from the one asked by more than this fraction is announced, with
why (docs/usage.md, "The bias test's mesh, shear angles and load steps")."""


def _size_reason(r: dict, specimen, model: list[Term], used: tuple[float, float]) -> str:
    """Why the mesh's h differs from the one asked by more than :data:`SIZE_NOTE` ("" when it
    does not): a fibre-aligned lattice has a whole number of cells between fibre lines, so only
    some sizes fit the rectangle; for the corner-to-corner lattice, the fitting sizes on either
    side of the one asked."""
    asked, got = r["h_requested"], r["h_used"]
    if r["mesh_kind"] not in LATTICES or not abs(got - asked) > SIZE_NOTE * asked:
        return ""
    why = (
        f"h = {got:.4g} mm, {100 * (got / asked - 1):+.0f} % from the {asked:g} mm asked: "
        "a fibre-aligned mesh needs a whole number of cells between fibre lines along both "
        "sides of the specimen at the fibres' angle, so only some sizes fit it"
    )
    theta = symmetric_angle(used)
    if r["mesh_kind"] != "aligned" or theta is None:
        return why + "; the nearest that fits was taken"
    tol = max(min(tolerated_mismatch_deg(model), ANGLE_TOLERANCE_DEG), EXACT_DEG)
    finer, coarser = lattice_sizes(specimen.length, specimen.width, asked, theta, tol)
    sizes = " and ".join(f"{v:.4g} mm" for v in (finer, coarser) if v is not None)
    return (
        why + f"; near {asked:g} mm these are h = {sizes}, and the nearest in cell count "
        f"was taken"
        + (
            f" (for a mesh no coarser than asked: h = {finer:.4g} mm)"
            if finer is not None and got > asked
            else ""
        )
    )


def _notice(r: dict, why: str, size: str = "") -> str:
    lines = []
    if [float(a) for a in r["fibre_angles_given"]] != r["fibre_angles_used"]:
        lines.append(
            f"fibre angles {r['fibre_angles_given']} deg are the fibre lines "
            f"{r['fibre_angles_used']} deg (directions are defined mod 180 deg); "
            "computed with the latter"
        )
    head = (
        f"mesh: {r['mesh_kind']}"
        + (f" ({why})" if why else "")
        + f", h = {r['h_used']:.4g} mm (asked {r['h_requested']:g}), "
        f"K/k_s = {r['fibre_stiffness_ratio']:.3g}, fibre terms {r['fibre_treatment']}"
    )
    if r["may_lock"]:
        lines.append(
            "WARNING " + head + ": the answer may be LOCKED, too stiff by a factor "
            "that grows with K/k_s (intra-ply shear locking, docs/theory.md 'Locking'"
            + (
                "; the reduced treatment is too soft instead"
                if r["fibre_treatment"] == "reduced"
                else ""
            )
            + "). Remedy: "
            + _remedy(r)
        )
    elif r["mesh_kind"] != "aligned" or r["fibre_treatment"] != "full" or size:
        lines.append(head)
    if size:
        lines.append(size)
    return "\n".join(lines)


def _remedy(r: dict) -> str:
    if r["mesh_kind"] == "aligned" and r["angle_mismatch_deg"] > 0.0:
        return (
            "an h whose lattice has the fibres' angle exactly, or mesh = 'lattice_pair' "
            "(the angle exact by construction), or check the force against a run at h/2"
        )
    return (
        (
            "elastic fibres with K/k_s = 1e9 (within 1e-4 of the limit on fibre-aligned "
            "meshes), or "
            if math.isinf(r["fibre_stiffness_ratio"])
            else ""
        )
        + "fibres at +-theta to the load on a specimen longer than 2 W / tan(theta), which "
        "get a fibre-aligned mesh, or check the force against a run at h/2"
    )


def announce(comm: MPI.Comm, record: dict) -> None:
    """Log the record's notice on rank 0, if it has one: a warning (shown even with --quiet;
    its ``WARNING`` word left to the handler's ``warning:``) when the answer may be locked, else
    progress, each line a ``note: …``."""
    notice = record["notice"]
    if notice and record["may_lock"]:
        warn(logger, comm, notice.replace("WARNING ", "", 1))
    elif notice:
        rank0(logger, comm, "\n".join("note: " + line for line in notice.split("\n")))


def check_bias_angles(angles: tuple[float, float], length: float, width: float) -> None:
    """Refuse (ValueError naming the value) fibre pairs the bias test cannot have, before
    anything is computed: families closer than :data:`MIN_SEPARATION_DEG`; a family so close
    to the load axis (0°) that its fibres run from clamp to grip (φ ≤ atan(W/L): the test is
    then a tensile test of the yarns). Steep fibres, whose unsheared grip zones ((W/2)·cot φ
    long) are shorter than the mesh size, are computed: the fibre-aligned meshes resolve those
    zones whatever h (docs/theory.md, "Steep fibres")."""
    a, b = angles
    apart = abs(a - b) % 180.0
    apart = min(apart, 180.0 - apart)
    if apart < MIN_SEPARATION_DEG:
        raise ValueError(
            f"bias test: fibre angles {list(angles)} deg are {apart:.3g} deg apart "
            f"as lines; the families must cross at {MIN_SEPARATION_DEG:g} deg or "
            "more"
        )
    steepest = math.degrees(math.atan(width / length))
    for phi in (abs(a), abs(b)):
        if phi <= steepest:
            raise ValueError(
                f"bias test: fibres at {phi:g} deg to the load run from clamp to grip on a "
                f"{length:g} x {width:g} mm specimen (they must make more than "
                f"atan(W/L) = {steepest:.3g} deg with it): the test degenerates into a tensile "
                "test of the yarns; cut the specimen on the bias (e.g. +-45 deg) or longer"
            )


def specimen_mesh(
    length: float,
    width: float,
    h: float,
    fibre_angles: tuple[float, float],
    comm: MPI.Comm = MPI.COMM_WORLD,
    mesh: str = "auto",
    model: list[Term] | None = None,
) -> Specimen:
    """The bias specimen [0, length] × [0, width] meshed with size ``h`` (``mesh``: see
    :data:`fabricsurf.geometry.fibre_mesh.MESH_KINDS`), with the points A and B of
    :func:`~fabricsurf.geometry.specimen.bias_points`; for ``model``'s fibres, ``auto`` takes no
    corner-to-corner lattice so far off their angle that they would lock it."""
    check_positive(length=length, width=width, h=h)
    if width > length:
        raise ValueError(
            f"geometry: width {width} exceeds length {length}; the bias specimen "
            "has its long side along the load"
        )
    return bias_mesh(
        length,
        width,
        h,
        fibre_angles,
        comm,
        mesh,
        extra_points=bias_points(length, width),
        max_mismatch_deg=tolerated_mismatch_deg(model or []),
    )
