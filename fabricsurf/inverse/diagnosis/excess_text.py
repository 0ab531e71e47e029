"""The words of :mod:`.excess`: its verdicts, the reason with its numbers, the outcome's note."""

from __future__ import annotations

WORDS = {
    "boundary": "boundary/discreteness",
    "spread": "spread (a missing energy, or the specimen as a whole)",
    "none": "no significant excess",
    "undecided": "undecided",
}


def reason(rec: dict, unit: str) -> str:
    """Why the verdict, in words with its numbers."""
    nr, v = rec["near"], rec["verdict"]
    if v is None:
        return rec["reason"]
    if v == "none":
        return (
            f"the field's mean z² is {rec['mean_z2']:.3g}, within the adequacy bound "
            f"{rec['adequacy_bound']:.3g}: no excess to locate"
        )
    near = (
        f"within 1 {unit} of the grips and zone boundaries lie "
        f"{100 * nr['share_of_excess']:.0f} % of the field's excess χ² on "
        f"{100 * nr['share_of_rows']:.0f} % of the rows (mean z² "
        + (f"{nr['mean_z2']:.3g}" if nr["mean_z2"] is not None else "–")
        + " against "
        + (f"{nr['mean_z2_elsewhere']:.3g}" if nr["mean_z2_elsewhere"] is not None else "–")
        + " elsewhere, "
        + (f"{nr['mean_z2_expected']:.3g}" if nr["mean_z2_expected"] is not None else "–")
        + " expected from the rows beyond at the same step and shear angle"
        + (f"; F-test p = {nr['p']:.2g}" if nr["p"] is not None else "")
        + ")"
    )
    if v == "boundary":
        return (
            near + ": a misfit at the scale of the yarns that the continuum cannot represent; no "
            "energy term will take it"
            + (
                "; the rest holds a significant excess of its own too"
                if rec["far_significant"]
                else ""
            )
        )
    if v == "spread":
        return near + (
            "; the rest of the specimen carries an excess of its own: a missing energy, or a "
            "misfit of the specimen as a whole (its size, grips or free edges) that where the "
            "excess sits cannot tell from one"
        )
    if not nr["judgeable"]:
        return near + f"; that band is too wide to show a concentration (1 {unit}: finer data)"
    return near + "; too few rows away from them to tell a spread excess"


def outcome_text(rec: dict | None) -> str:
    """ "" or "where the excess sits: …" (the verdict and its reason) when a claim is made."""
    if not rec or rec.get("verdict") not in ("boundary", "spread"):
        return ""
    return f"where the excess sits: {WORDS[rec['verdict']]}: {rec['reason']}"
