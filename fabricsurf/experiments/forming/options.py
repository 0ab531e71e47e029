"""The options of the hemisphere forming plug-in (experiments/hemisphere.py) and their checks,
all made before any computation: each message names the key, its value and the range it must
lie in.

The ranges are those of the model, not of taste: the die's clearance, lip and the holder's
gap are tools on the scale of the punch; the contact penalty must keep the holder's own
penetration p_h/k_c (the offset of the die's face) well inside the holder's gap; a Coulomb
coefficient of a fabric on tools is a fraction of one; a shear angle lies below 90°. The blank
may be at most :data:`MAX_BLANK_RATIO` punch radii wide (the default mesh, h = R/6, then has a
few thousand cells), and a mesh of more than :data:`MAX_ELEMENTS` cells on the quarter, default
h or given, is refused before meshing. A stroke must leave the blank's edge on the die's face
(:func:`max_stroke`).
"""

from __future__ import annotations

import math

from fabricsurf.errors import DataError
from fabricsurf.experiments.base import PluginSetup, number_option
from fabricsurf.experiments.cantilever import areal_density_option
from fabricsurf.experiments.forming.surfaces.files import (
    FILE_KEYS,
    given_surface,
    tool_file_options,
)
from fabricsurf.experiments.forming.surfaces.holder import footprint_of, unheld_by
from fabricsurf.experiments.forming.surfaces.opening import Opening

TOOL_KEYS = {
    "punch_radius": "punch radius R (mm, required)",
    "clearance": "die opening radius minus R (mm, default R/5)",
    "die_lip": "lip radius of die and holder (mm, default R/5)",
    "holder_gap": "gap between holder and die (mm, default R/50)",
    "holder_pressure": "pressure of the holder on the flange (N/mm², default 1e-3)",
    "contact_stiffness": "penalty k_c (N/mm³, default 100)",
    "friction": "Coulomb coefficient between the flange and holder and die's face (default 0)",
    "punch_friction": "Coulomb coefficient between the sheet and the punch (default 0)",
    "die_friction": "Coulomb coefficient between the sheet and the die's lip (default 0)",
    "friction_slip_rate": "slip rate below which friction is regularised (mm of slip per "
    "mm of stroke, default 0.01)",
    "locking_angle_deg": "shear angle beyond which the fabric jams (deg, default 50)",
    "wrinkle_tension": "compressive fibre tension of the wrinkling indicator (N/mm, default 1e-3)",
    "wrinkle_curvature": "normal curvature of the wrinkling indicator (1/mm, default 1/R: "
    "bent more sharply than the punch)",
    "die_opening_length": "length along x of a rectangular opening of die and holder (mm; "
    "default: the circle of radius R + clearance)",
    "die_opening_width": "its width along y (mm, default 2(R + clearance))",
    "die_corner_radius": "its corner radius (mm, default half the shorter side: round ends)",
    "contact_softening": "softening ε of the punch's contact (mm, default 0: the plain "
    "penalty; a punch with a large flat top needs about 1e-3)",
    "stabilisation": "viscous drag η on the sheet's motion per unit stroke (N/mm², default 0: "
    "off; the run reports the energy it dissipated)",
    **FILE_KEYS,
}
"""The tools' keys of the ``[tooling]`` table (the blank's: forming/blank.py)."""

MATERIAL_KEYS = {
    "areal_density_g_m2": "areal density for self-weight (g/m², gravity 9.81 m/s² "
    "along −z; default: no self-weight)"
}
"""The plug-in's keys of the ``[material]`` table."""

DEFAULTS = {"clearance": 0.2, "die_lip": 0.2, "holder_gap": 0.02}
"""Tool sizes as fractions of the punch radius R (a mesh must resolve the clearance and the
lip, h ≤ min of the two, for the punch force to converge: docs/forming.md)."""
CONTACT_STIFFNESS = 100.0
"""Default penalty k_c (N/mm³): a contact pressure p gives a penetration p / k_c."""
LOCKING_ANGLE_DEG = 50.0
"""Default locking angle (woven fabrics lock at about 40–55°, Cao et al. 2008)."""
PLAIN_DEFAULTS = {
    "contact_stiffness": CONTACT_STIFFNESS,
    "holder_pressure": 1e-3,
    "friction_slip_rate": 1e-2,
    "locking_angle_deg": LOCKING_ANGLE_DEG,
    "wrinkle_tension": 1e-3,
}
"""Defaults of the options in their own units (N/mm³, N/mm², mm/mm, deg, N/mm)."""
RANGES = {
    "clearance": (0.0, 1.0, "R"),
    "die_lip": (0.0, 1.0, "R"),
    "holder_pressure": (0.0, 1.0, "N/mm²"),
    "contact_stiffness": (0.0, 1e6, "N/mm³"),
    "friction": (0.0, 2.0, ""),
    "punch_friction": (0.0, 2.0, ""),
    "die_friction": (0.0, 2.0, ""),
    "friction_slip_rate": (0.0, 1.0, "mm/mm"),
    "locking_angle_deg": (0.0, 90.0, "deg"),
    "stabilisation": (0.0, 1.0, "N/mm²"),
}
"""(low, high, unit) of each option: low excluded (the Coulomb coefficients and the
stabilisation: included), high included; "R": in punch radii."""
FRICTION_KEYS = ("friction", "punch_friction", "die_friction")
"""Coulomb coefficients (default 0: frictionless) of the flange under the holder (both faces),
of the punch and of the die's lip (forming_tools, forming_friction)."""
ZERO_ALLOWED = (*FRICTION_KEYS, "stabilisation")
"""Options whose default is 0 (off) and whose range includes it."""
MAX_BLANK_RATIO = 20.0
"""The blank's side at most this many punch radii (forming tests: 3 to 6)."""
MAX_ELEMENTS = 400_000
"""Cells of the quarter's mesh at most (about 20 GB with the 3D model and MUMPS)."""
SOFTENING_LIMIT = 0.01
"""The punch's contact softening at most this fraction of the die's lip radius."""
PENETRATION_FRACTION = 0.1
"""The holder's own penetration p_h / k_c at most this fraction of the holder's gap."""


def _ranged(out: dict, key: str, where: str, R: float) -> None:
    low, high, unit = RANGES[key]
    scale, shown = (R, f" (= {high:g} R = {high * R:g} mm)") if unit == "R" else (1.0, "")
    v = out[key]
    closed = key in ZERO_ALLOWED
    if v < low * scale or (v == low * scale and not closed) or v > high * scale:
        lo = f"{low:g} ≤" if closed else f"{low:g} <"
        raise DataError(
            f"{where}: [tooling] {key} = {v:g} is outside its plausible range "
            f"{lo} {key} ≤ {high:g}{' ' + unit if unit else ''}{shown}"
        )


def parse(tables: dict, length_scale: float, where: str) -> dict:
    """The ``[tooling]`` and ``[material]`` keys (docs/forming.md) in mm, N, checked."""
    R = number_option(tables, "tooling", "punch_radius", where) * length_scale
    out = {"punch_radius": R}
    for key, frac in DEFAULTS.items():
        default = frac * R / length_scale
        out[key] = number_option(tables, "tooling", key, where, default) * length_scale
    for key, default in PLAIN_DEFAULTS.items():
        out[key] = number_option(tables, "tooling", key, where, default)
    for key in ZERO_ALLOWED:
        out[key] = number_option(tables, "tooling", key, where, 0.0, positive=False)
    for key in RANGES:
        _ranged(out, key, where, R)
    if out["holder_gap"] > out["die_lip"]:
        raise DataError(
            f"{where}: [tooling] holder_gap = {out['holder_gap']:g} mm is wider "
            f"than the die's lip ({out['die_lip']:g} mm): the holder would not "
            f"hold the flange; plausible range 0 < holder_gap ≤ die_lip"
        )
    sink = out["holder_pressure"] / out["contact_stiffness"]
    if sink > PENETRATION_FRACTION * out["holder_gap"]:
        need = out["holder_pressure"] / (PENETRATION_FRACTION * out["holder_gap"])
        raise DataError(
            f"{where}: [tooling] contact_stiffness = {out['contact_stiffness']:g} "
            f"N/mm³ lets the holder's pressure sink the flange {sink:.3g} mm into "
            f"the die, more than a tenth of holder_gap ({out['holder_gap']:g} mm); "
            f"plausible range {need:.3g} ≤ contact_stiffness ≤ "
            f"{RANGES['contact_stiffness'][1]:g} N/mm³"
        )
    out.update(_opening(tables, length_scale, where, out))
    soft = number_option(tables, "tooling", "contact_softening", where, 0.0, positive=False)
    out["contact_softening"] = soft * length_scale
    if not 0.0 <= out["contact_softening"] <= SOFTENING_LIMIT * out["die_lip"]:
        raise DataError(
            f"{where}: [tooling] contact_softening = {soft:g} is outside its plausible range "
            f"0 ≤ contact_softening ≤ {SOFTENING_LIMIT:g} die_lip (= "
            f"{SOFTENING_LIMIT * out['die_lip']:g} mm)"
        )
    out.update(tool_file_options(tables.get("tooling", {}), where))
    out["areal_density_g_m2"] = areal_density_option(tables, where, 0.0)
    out["wrinkle_curvature"] = (
        number_option(tables, "tooling", "wrinkle_curvature", where, 1.0 / R * length_scale)
        / length_scale
    )
    return out


OPENING_KEYS = ("die_opening_length", "die_opening_width", "die_corner_radius")


def _opening(tables: dict, length_scale: float, where: str, o: dict) -> dict:
    """The rectangular opening's keys in mm, checked, if any is given (else none: the circle of
    radius R + clearance); their defaults make a slot with round ends of width 2(R + clearance)."""
    tooling = tables.get("tooling", {})
    if not any(k in tooling for k in OPENING_KEYS):
        return {}
    side = 2.0 * (o["punch_radius"] + o["clearance"]) / length_scale
    L, W = (number_option(tables, "tooling", k, where, side) for k in OPENING_KEYS[:2])
    c = number_option(tables, "tooling", OPENING_KEYS[2], where, 0.5 * min(L, W), positive=False)
    if not 0.0 <= c <= 0.5 * min(L, W):
        raise DataError(
            f"{where}: [tooling] die_corner_radius = {c:g} is outside its range 0 ≤ "
            f"die_corner_radius ≤ {0.5 * min(L, W):g} (half the opening's shorter side)"
        )
    return dict(zip(OPENING_KEYS, (v * length_scale for v in (L, W, c)), strict=True))


def opening(o: dict) -> Opening:
    """The die's and the holder's opening of the checked options (surfaces/opening.py)."""
    if "die_opening_length" not in o:
        return Opening.circle(o["punch_radius"] + o["clearance"])
    L, W, c = (o[k] for k in OPENING_KEYS)
    return Opening("rectangle", 0.5 * L, 0.5 * W, c)


def uncovered(o: dict, half_x: float, half_y: float, round_blank: bool = False) -> str | None:
    """Why a blank reaching ``half_x``, ``half_y`` from the axis along x and y (a disc of
    radius ``half_x`` if ``round_blank``) does not cover the die's opening with its lip, or
    None."""
    op, lip = opening(o), o["die_lip"]
    if round_blank and half_x > op.outer_reach + lip:
        return None
    if not round_blank and min(half_x - op.half_length, half_y - op.half_width) > lip:
        return None
    if op.kind == "circle":
        need = 2 * (op.corner + lip)
        return f"the die opening with its lip, 2(R + clearance + die_lip) = {need:g} mm"
    return (
        f"the die's {op.name} with its lip, {2 * (op.half_length + lip):g} × "
        f"{2 * (op.half_width + lip):g} mm"
    )


def check_specimen(setup: PluginSetup, where: str) -> None:
    """A square blank wider than the die's opening with its lip, at most
    :data:`MAX_BLANK_RATIO` punch radii wide."""
    o = setup.options
    R, short = o["punch_radius"], uncovered(o, 0.5 * setup.length, 0.5 * setup.width)
    if setup.length != setup.width or short is not None:
        raise DataError(
            f"{where}: the blank {setup.length:g} × {setup.width:g} mm must be "
            f"a square wider than {short or 'the die opening with its lip'}"
        )
    if setup.length > MAX_BLANK_RATIO * R:
        raise DataError(
            f"{where}: [tooling] punch_radius = {R:g} mm is implausibly small "
            f"for a {setup.length:g} mm blank (at most {MAX_BLANK_RATIO:g} punch "
            f"radii wide; plausible range punch_radius ≥ "
            f"{setup.length / MAX_BLANK_RATIO:g} mm): is it in another unit?"
        )


def check_mesh(setup: PluginSetup, h: float, default: bool) -> None:
    """Refuse an element size whose quarter mesh would exceed :data:`MAX_ELEMENTS` cells
    (estimated before meshing as 2 per h × h square)."""
    n = 2 * math.ceil(0.5 * setup.length / h) * math.ceil(0.5 * setup.width / h)
    if n > MAX_ELEMENTS:
        what = f"the default h = R/6 = {h:g} mm" if default else f"h = {h:g} mm"
        raise DataError(
            f"hemisphere: {what} would mesh the quarter of the {setup.length:g} × "
            f"{setup.width:g} mm blank with about {n:,} cells, more than {MAX_ELEMENTS:,}: "
            f"give a larger h (at least "
            f"{math.sqrt(setup.length * setup.width / (2 * MAX_ELEMENTS)):.3g} mm)"
        )


def unheld_edge(o: dict, half_x: float, half_y: float, round_blank: bool = False) -> str | None:
    """Why the flange at the middle of the blank's sides is not held, or None: the holder's
    pressure rises from zero at σ = 2 die_lip beyond the opening's outline to its full value
    one lip radius further (forming_tools.Tools.holder_weight); a blank whose edge, ``half_x``
    and ``half_y`` from the axis along x and y (a disc of radius ``half_x`` if ``round_blank``),
    ends before that leaves the flange there held by the holder's gap alone, free to buckle. A
    demo blank of B/2 = 1.5 R (against 1.8 R) did, and Newton then followed the stroke only
    with many cut steps (docs/forming.md)."""
    op, lip = opening(o), o["die_lip"]
    if (holder := given_surface(o, "holder")) is not None:
        return unheld_by(footprint_of(holder), lip, half_x, half_y, round_blank)
    full = (op.half_length + 3.0 * lip, op.half_width + 3.0 * lip)
    if round_blank:
        full = (op.outer_reach + 3.0 * lip,) * 2
    if half_x >= full[0] and half_y >= full[1]:
        return None
    if op.kind == "circle":
        where = f"R + clearance + 3 die_lip = {full[0]:g} mm"
        need = f"a blank of side at least {2.0 * full[0]:g} mm"
    else:
        where = f"the opening's half-sides + 3 die_lip = {full[0]:g}, {full[1]:g} mm"
        need = f"a blank at least {2.0 * full[0]:g} × {2.0 * full[1]:g} mm"
    return (
        f"hemisphere: the middle of the {2 * half_x:g} × {2 * half_y:g} mm blank's sides "
        f"({min(half_x, half_y):g} mm from the axis) lies inside where the holder's pressure "
        f"is full ({where}): the flange there is held by the holder's gap alone and may "
        f"buckle (wrinkles, cut steps); {need} is held all round"
    )


def lip_reach(o: dict) -> float:
    """The distance from the axis to the nearest point where the die's face is flat (mm)."""
    return opening(o).inner_reach + o["die_lip"]


def max_stroke(o: dict, blank: float) -> float:
    """The largest stroke that can leave the blank's edge on the die's face: every material
    line of a net of inextensible fibres stretches at most by √2 (sheared to the limit), every
    reference path from the centre to the edge is at least B/2 long, and any path from the
    pole at stroke s around the lip to the die's face, at least ρ = :func:`lip_reach` from the
    axis, at least as long as the straight line, √(s² + ρ²): s ≤ √(B²/2 − ρ²)."""
    return math.sqrt(max(0.5 * blank**2 - lip_reach(o) ** 2, 0.0))


def check_stroke(o: dict, blank: float, stroke: float) -> None:
    top = max_stroke(o, blank)
    if not (math.isfinite(stroke) and 0.0 < stroke <= top):
        raise DataError(
            f"hemisphere: stroke {stroke:g} mm is outside 0 < stroke ≤ {top:.4g} mm:"
            f" a {blank:g} mm blank would be drawn over the die's lip ({lip_reach(o):g} mm "
            "from the axis to the die's face) before that, even with its fibres sheared to "
            "the limit"
        )
