"""Moduli files (``--params``): {"term": {"parameter": value}} or a saved fit/diagnosis JSON
(its "params"), validated against the vocabulary and the model's terms; provenance records."""

from __future__ import annotations

import json
import math
import platform
from pathlib import Path

from fabricsurf.errors import InputError
from fabricsurf.model.terms import EFFECTS, Term

MAX_MODULUS = 1e12
"""The largest modulus accepted, in its own unit (N/mm, or N·mm for a second gradient; lengths
in mm). Well beyond any sheet: a 10 mm steel plate has E·t ≈ 2e6 N/mm and E·t³/12 ≈ 2e7 N·mm,
and the stiffest inextensibility penalty in use, K/k_s = 1e9 at k_s ≲ 1 N/mm, is 1e9 N/mm. Not
beyond the arithmetic: a tangent matrix whose entries span 1e12 over the soft moduli (≳ 1 N/mm)
keeps about 4 of double precision's 16 digits for them; beyond it the shear response drowns in
round-off and the Newton solve fails steps later (k_l = 1e308 overflows the energy)."""

OTHER_KINDS = (
    ({"combined", "chi2"}, "a misfit report (the misfit.json of compare, fit or diagnose)"),
    (
        {"baseline", "verdict"},
        "a diagnosis (diagnosis.json; its final model is saved as "
        "model_best.json by diagnose --add-best)",
    ),
    ({"error"}, "a failure report (failure.json)"),
    ({"ubar", "force"}, "the summary of a bias run (summary.json)"),
)
"""Outputs that are not moduli files, by the keys that mark them."""


def _other_kind(data: dict) -> str | None:
    """What ``data`` is when it is one of the outputs of OTHER_KINDS (and names no term)."""
    if any(k in EFFECTS for k in data):
        return None
    return next((kind for keys, kind in OTHER_KINDS if keys <= set(data)), None)


class _DuplicateKeyError(ValueError):
    pass


def _no_duplicates(pairs: list[tuple[str, object]]) -> dict:
    """A JSON object whose keys are unique (json keeps the last of a repeated key silently)."""
    seen = {}
    for k, v in pairs:
        if k in seen:
            raise _DuplicateKeyError(k)
        seen[k] = v
    return seen


def load_params(path: str | Path | None, terms: list[str] | None = None) -> dict:
    """{term: {param: value}} from a JSON file, every name and value checked. ``terms``: the
    model's terms (a term in the file but not in the model is an error, not ignored). Names
    are those of the registry :data:`EFFECTS` (the built-ins and the user's registered
    effects); a modulus is ≥ 0 unless its term declares it ``signed``."""
    if not path:
        return {}
    name = str(path)
    try:
        data = json.loads(
            Path(path).read_text(encoding="utf-8-sig"), object_pairs_hook=_no_duplicates
        )
    except OSError as e:
        raise InputError(f"--params {name}: cannot read ({e.strerror})") from None
    except _DuplicateKeyError as e:
        raise InputError(
            f"--params {name}: key '{e}' is given twice in one object (JSON "
            "keeps only the last; remove one)"
        ) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"--params {name}: not valid JSON ({e})") from None
    if isinstance(data, dict) and isinstance(data.get("params"), dict):
        data = data["params"]
    kind = _other_kind(data) if isinstance(data, dict) else None
    if kind:
        raise InputError(
            f"--params {name}: this is {kind}, not a moduli file; give "
            '{"term": {"parameter": value}}, a fit.json or a model_best.json'
        )
    if not isinstance(data, dict) or not data:
        raise InputError(
            f'--params {name}: expected {{"term": {{"parameter": value}}}}, got '
            f"{type(data).__name__}"
        )
    for term, vals in data.items():
        if term not in EFFECTS:
            raise InputError(
                f"--params {name}: unknown term '{term}' (valid: {', '.join(EFFECTS)})"
            )
        if terms is not None and term not in terms:
            raise InputError(
                f"--params {name}: term '{term}' is not in the model "
                f"({','.join(terms)}); add it to --terms or remove it"
            )
        if not isinstance(vals, dict):
            raise InputError(
                f'--params {name}: "{term}" must map parameters to values, e.g. '
                f'{{"{term}": {{"{EFFECTS[term].parameters()[0]}": 1.0}}}}'
            )
        if not vals:
            raise InputError(
                f"--params {name}: term '{term}' gives no parameter (it has "
                f"{', '.join(EFFECTS[term].parameters())}); give its moduli, or "
                "leave it out and name it in --terms to start from the defaults"
            )
        for p, v in vals.items():
            if p not in EFFECTS[term].parameters():
                raise InputError(
                    f"--params {name}: term '{term}' has no parameter '{p}' (it "
                    f"has {', '.join(EFFECTS[term].parameters())})"
                )
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            signed = p in EFFECTS[term].signed
            if not ok or (v < 0 and not signed):
                raise InputError(
                    f"--params {name}: {term}.{p} = {v!r} must be a finite "
                    f"number{'' if signed else ' ≥ 0'} "
                    f"({EFFECTS[term].units.get(p, '')})"
                )
            if abs(v) > MAX_MODULUS:
                unit = EFFECTS[term].units.get(p, "")
                raise InputError(
                    f"--params {name}: {term}.{p} = {v:.3g} {unit} is beyond any "
                    f"sheet (at most {MAX_MODULUS:.0e} {unit}: a 10 mm steel plate "
                    "is ~2e6 N/mm, a near-inextensible fibre penalty ~1e9 N/mm; "
                    "more leaves the solver no digits for the other moduli); "
                    "check the value and its unit (moduli in N/mm and N·mm, "
                    "lengths in mm)"
                )
    return data


def parse_model(spec: str | None, params: dict) -> list[Term]:
    """The model of ``--terms`` (default: the terms of the params file); duplicates rejected."""
    from fabricsurf.model.terms import parse_terms

    spec = spec or ",".join(params)
    if not spec:
        raise InputError("--terms: no terms given (and no --params file naming them)")
    names = [s.strip() for s in spec.split(",") if s.strip()]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"--terms: '{dup[0]}' is given twice")
    try:
        return parse_terms(spec, params)
    except ValueError as e:
        raise InputError(f"--terms: {e}") from None


def provenance(model: list[Term], inputs: list[str], h: list[float] | None = None) -> dict:
    """What produced an output: terms and moduli, mesh sizes, inputs, software versions."""
    import dolfinx
    import petsc4py
    from mpi4py import MPI

    from fabricsurf import __version__

    return {
        "terms": [t.name for t in model],
        "params": {t.name: t.values() for t in model},
        "h_mm": h,
        "inputs": inputs,
        "ranks": MPI.COMM_WORLD.size,
        "versions": {
            "fabricsurf": __version__,
            "dolfinx": dolfinx.__version__,
            "petsc4py": petsc4py.__version__,
            "python": platform.python_version(),
        },
    }
