"""The results in words, as the command line prints them (and the demos, after it): a fit's
moduli with their 95 % intervals and the combinations the data determine (fit.json, a
diagnosis's final model), the misfits of a compare or fit (misfit.json), and a diagnosis's tie
with the experiment that would separate it. Text only: what is computed, and written to JSON,
is in :mod:`~.report` and the fitting layer."""

from __future__ import annotations

from fabricsurf.inverse.diagnosis.excess_text import WORDS


def _num(x: float | None) -> str:
    return "not measured" if x is None else f"{x:.2g}"


def result_lines(u: dict) -> list[str]:
    """The fitted moduli of a fit.json or a diagnosis's final model ``u``: each identifiable
    one with its 95 % interval and the parts of its uncertainty; one that is not gets no ± (it
    would span zero or be a meaningless 1e-13), and the combinations the data do determine are
    given with their intervals, then those they do not. A modulus held at its stiff limit
    (``at_stiff_limit``, :mod:`~fabricsurf.inverse.fitting.stiff_limit`) says so."""
    lines, stiff = [], u.get("at_stiff_limit") or {}
    for n, m in u["moduli"].items():
        if m.get("fixed"):
            lines.append(f"  {n} = {m['value']:.5g} (held)")
        elif n in stiff:
            lines.append(
                f"  {n} = {m['value']:.5g} (held at its stiff limit: the data do not bound it "
                f"above; at infinity chi2 would be {stiff[n]:.2g} lower)"
            )
        elif m["identifiable"]:
            lo, hi = m["ci95"]
            lines.append(
                f"  {n} = {m['value']:.5g}, 95 % interval [{lo:.4g}, {hi:.4g}] "
                f"(statistical σ {m['std_statistical']:.2g}, mesh "
                f"{_num(m['systematic_mesh'])}, model form "
                f"{_num(m['systematic_model'])})"
            )
        else:
            lines.append(f"  {n} = {m['value']:.5g} (not determined by the data on its own)")
    for c in u["identifiable_combinations"]:
        lo, hi = c["ci95"]
        lines.append(
            f"  determined combination: {c['combination']} = {c['value']:.5g}, "
            f"95 % interval [{lo:.4g}, {hi:.4g}]"
        )
    for c in u.get("undetermined", []):
        lines.append(f"  not determined by the data (rank-deficient Fisher matrix): {c}")
    for w in u["weak_directions"]:
        lines.append(f"  weak direction (log-moduli, σ {w['std_log']:.2g}): {w['direction']}")
    return lines


def misfit_summary(label: str, m: dict) -> str:
    """The combined misfit of a misfit.json ``m`` and each experiment's, as the CLI prints
    them after compare and fit."""
    parts = [
        f"{label}: combined misfit {m['combined']:.4g} (noise units), chi2 "
        f"{m['chi2']:.5g} over {m['n']} data"
    ]
    for e in m["experiments"]:
        bits = [
            f"field RMS {e['field_rms']:.4g} mm" if e["field_rms"] is not None else "",
            f"force RMS {e['force_rms']:.4g} N" if e["force_rms"] is not None else "",
            f"shear RMS {e['shear_rms_deg']:.4g} deg" if e.get("shear_rms_deg") is not None else "",
        ]
        parts.append(
            f"  {e['experiment']}: misfit {e['combined']:.4g}; "
            + ", ".join(b for b in bits if b)
            + (f"; points outside the mesh: {e['points_outside']}" if e["points_outside"] else "")
        )
    return "\n".join(parts)


def tie_lines(d) -> list[str]:
    """The tie and the separating experiment, as text (docs/diagnosis.md, "Ties")."""
    if not d.tied():
        return []
    lines = []
    for c in d.tie.comparisons:
        if c["tied"]:
            lines.append(
                f"tie: {' or '.join(c['effects'])}: chi2 {c['chi2'][0]:.6g} vs "
                f"{c['chi2'][1]:.6g}, difference {c['delta_chi2']:.3g} against a resolution "
                f"of {c['resolution']:.3g} (Vuong z = {c['z']:.2f}, p = {c['p']:.3g}); their "
                f"predictions differ by {c['prediction_difference']:.3g} noise units over all "
                f"the data; cosine of their sensitivities {c['cosine']:.4f}"
            )
    sep = d.separating_experiment or {}
    best, own = sep.get("suggested"), sep.get("as_measured", {})
    if own:
        where = own.get("where_they_differ_most")
        lines.append(
            f"  the data's own test separates them by S = {own['separation']:.3g} "
            f"(expected z ≈ √S/2 = {own['expected_z']:.2f})"
            + (
                f"; they differ most at x {where['x_mm'][0]:.3g}–{where['x_mm'][1]:.3g}"
                f" mm, y {where['y_mm'][0]:.3g}–{where['y_mm'][1]:.3g} mm "
                f"({where['share_of_separation']:.0%} of it)"
                if where
                else ""
            )
        )
    if best:
        lines.append(
            f"separating experiment: {best['description']}: S = "
            f"{best['separation']:.3g}, expected z ≈ {best['expected_z']:.2f} "
            + ("(separates: above " if best["separates"] else "(not enough: below ")
            + f"{sep['z_critical']:.2f}); reliably (98 %) with "
            f"{best['data_factor']:.2g}× its points, steps or 1/noise²"
            + (
                "; map: tie_difference_map.png"
                if own.get("where_they_differ_most") or best.get("key") == "field_data"
                else ""  # force only, as measured and as suggested: nothing to map
            )
        )
        for q in sep["candidates"][1:]:
            lines.append(
                f"  then: {q['description']}: "
                + (
                    f"S = {q['separation']:.3g}"
                    if q["separation"] is not None
                    else f"not run ({q['failed']})"
                )
            )
    return lines


def _band(b: dict, unit: str) -> str:
    hi = "" if b["to"] is None else f"{b['to']:g}"
    span = f"≥ {b['from']:g}" if b["to"] is None else f"{b['from']:g}–{hi}"
    share = "–" if b["share_of_excess"] is None else f"{100 * b['share_of_excess']:.0f} %"
    return (
        f"    {span} {unit}: {100 * b['share_of_rows']:.0f} % of the rows, {share} of the "
        f"excess (mean z² {b['mean_z2']:.3g})"
    )


def excess_lines(rec: dict | None) -> list[str]:
    """Where the excess sits (docs/diagnosis.md, "Where the excess sits"), as text."""
    if not rec:
        return []
    if rec.get("verdict") is None:
        return [f"where the excess sits: {rec['reason']}"]
    unit = "yarn spacings" if rec.get("yarn_spacing_mm") else "mesh sizes h"
    size = (
        f"{rec['yarn_spacing_mm']:g} mm"
        if rec.get("yarn_spacing_mm")
        else ", ".join(f"{x:.3g}" for x in rec["unit_mm"]) + " mm (yarn spacing not given)"
    )
    lines = [f"where the excess sits: {WORDS[rec['verdict']]}: {rec['reason']}"]
    lines.append(f"  by distance from the grips and zone boundaries (1 unit = {size}):")
    lines += [_band(b, unit) for b in rec["by_distance"]]
    lines.append("  by the model's shear angle:")
    lines += [_band(b, "deg") for b in rec["by_shear_angle"]]
    return lines


def implausible_lines(found: list | None) -> list[str]:
    """The fitted moduli no fabric has, each with what it stands in for and what to do."""
    return [f"implausible modulus: {q['text']}" for q in found or []]
