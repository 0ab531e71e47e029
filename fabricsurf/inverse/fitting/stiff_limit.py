"""A modulus that runs to its stiff limit: recognised during a fit and held there.

When the data cannot see a stiffness (yarns that hardly stretch in a bias test at 2 % stretch),
the misfit keeps falling as the modulus grows, ever more slowly. For a large modulus p the
response approaches its inextensible limit as u∞ + a/p, so χ²(p) ≈ χ²∞ + c/p, and the gain still
to be had by going to p → ∞ is R = −p ∂χ²/∂p, read off the exact sensitivities at no cost.
Linear Levenberg–Marquardt steps creep up that tail by a few per cent per forward run, for as
many iterations as the fit allows.

The watch (:class:`StiffWatch`) notices a modulus that rose in ``STIFF_RISES`` accepted steps in a
row while χ² fell by less than ``STIFF_SLOW`` of itself per step. Near the limit the response is
linear in the compliance 1/p, so a Gauss–Newton step in the compliance (:func:`beyond_limit`)
tells a tail (the best compliance ≤ 0: beyond the inextensible response) from a finite optimum,
at no cost. For a tail whose whole gain R is below ``STIFF_NEGLIGIBLE``, the modulus is held where
it is, without a run: a jump would buy nothing and could make the sheet stiff enough to slow
every Newton solve after it. Otherwise the fit tries the modulus × ``STIFF_JUMP`` (no larger
than ``STIFF_CAP``) with the others fixed (:func:`jump`). When χ² falls by what the tail form
predicts, within a factor of two, the modulus is held at the jumped value for the rest of the
fit. A held modulus is logged and reported in ``FitResult.at_limit`` with the gain left. Any other
outcome of the jump is an ordinary trial step: kept if χ² fell, else discarded, and the fit goes
on.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from fabricsurf.log import rank0

logger = logging.getLogger(__name__)

STIFF_RISES = 3
"""Accepted steps in a row that raised a modulus slowly before the jump is tried."""
STIFF_SLOW = 1e-3
"""A step is slow when χ² fell by less than this fraction of itself."""
STIFF_MOVE = 1e-2
"""The relative rise of the modulus in the last of those steps, at least: a modulus settling at
a finite optimum moves less and less, one creeping up the tail does not."""
STIFF_JUMP = 1e3
"""The factor the jump tries: the gain left falls by as much under the tail form."""
STIFF_NEGLIGIBLE = 1.0
"""A gain to infinity below this (one unit of χ², the Δχ² of a 68 % interval) is not worth a run:
the moduli are held where they are."""
STIFF_CAP = 1e10
"""The largest modulus the jump tries (N/mm or N·mm): a hundredth of ``params.MAX_MODULUS``,
so that the tangent keeps digits for the soft moduli (its docstring)."""


@dataclass
class StiffWatch:
    """Per free modulus (``signed`` ones are never watched): the count of slow rises in a row,
    and which moduli are held at their stiff limit."""

    signed: np.ndarray
    rises: np.ndarray = field(init=False)
    held: np.ndarray = field(init=False)
    left: np.ndarray = field(init=False)
    """Per held modulus, the gain χ² would still make at infinity (the tail form's)."""

    def __post_init__(self) -> None:
        self.rises = np.zeros(len(self.signed), int)
        self.held = np.zeros(len(self.signed), bool)
        self.left = np.zeros(len(self.signed))

    def hold(self, which: np.ndarray, gain: np.ndarray) -> None:
        """Hold the moduli ``which``, with their tail gains ``gain`` left."""
        self.held |= which
        self.left = np.where(which, np.maximum(gain, 0.0), self.left)

    def observe(self, old: np.ndarray, new: np.ndarray, rel_gain: float) -> np.ndarray:
        """Count an accepted step (the free moduli before and after, χ²'s relative fall);
        the mask of moduli that have risen slowly ``STIFF_RISES`` times in a row, the last time
        by ``STIFF_MOVE`` of themselves at least."""
        up = ~self.signed & ~self.held & (new > old) & (rel_gain < STIFF_SLOW)
        self.rises = np.where(up, self.rises + 1, 0)
        far = new >= old * (1.0 + STIFF_MOVE)
        return (self.rises >= STIFF_RISES) & far & (new < STIFF_CAP)


def tail_gain(p: np.ndarray, Jr: np.ndarray, r: np.ndarray) -> np.ndarray:
    """R = −p ∂χ²/∂p per free modulus (χ² = r·r, ``Jr`` = dr/dp): the gain to p → ∞ when
    χ² ≈ χ²∞ + c/p (module docstring)."""
    return -2.0 * p * (Jr.T @ r)


def beyond_limit(p: np.ndarray, Jr: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Per free modulus: does the Gauss–Newton step in its compliance c = 1/p, the others
    fixed, land at c ≤ 0? Near the stiff limit the response is linear in c (u∞ + a·c), so that
    step finds the best compliance; a finite optimum has c > 0 and is left to the fit. With
    dr/dc = −p² dr/dp the condition reads R ≥ 2 p² |dr/dp|², R the tail gain."""
    return gain >= 2.0 * p**2 * np.sum(Jr**2, axis=0)


def jump(vals: np.ndarray, free: list[int], chi2: float, gain: np.ndarray, ripe: np.ndarray, run):
    """Try the ``ripe`` moduli (tail gains ``gain``) at their stiff limit, ``run(trial)`` →
    (prediction, (r, Jr), χ²) as the fit's trial step: (trial, prediction, (r, Jr), χ², tail);
    ``tail``: χ² fell from ``chi2`` by what the tail form predicts, within a factor of two."""
    p = vals[free]
    factor = np.where(ripe, np.minimum(STIFF_JUMP, STIFF_CAP / p), 1.0)
    trial = vals.copy()
    trial[free] = p * factor
    pred, rj, chi2_new = run(trial)
    expected = float(np.sum(gain[ripe] * (1.0 - 1.0 / factor[ripe])))
    tail = 0.5 * expected <= chi2 - chi2_new <= 2.0 * expected  # False for a rise or inf
    return trial, pred, rj, chi2_new, tail


def hold(fm, free: list[int], watch: StiffWatch, ripe: np.ndarray, state: tuple, run) -> tuple:
    """From the fit's ``state`` (moduli, prediction, r, Jr, χ²), the ``ripe`` moduli whose best
    compliance is ≤ 0 (:func:`beyond_limit`): held where they are when the gain to infinity is
    below ``STIFF_NEGLIGIBLE``, else tried at their limit (:func:`jump`, ``run`` as there) and
    held there when χ² fell as the tail form predicts. Returns the state after."""
    vals, _, r, Jr, chi2 = state
    watch.rises[ripe] = 0
    gain = tail_gain(vals[free], Jr, r)
    ripe = ripe & beyond_limit(vals[free], Jr, gain)
    if not ripe.any():
        return state
    names = ", ".join(fm.names[k] for k, m in zip(free, ripe) if m)
    if gain[ripe].sum() < STIFF_NEGLIGIBLE:
        watch.hold(ripe, gain)
        rank0(
            logger,
            fm.comm,
            f"  fit: {names} held where it is (at infinity chi2 would be "
            f"{gain[ripe].sum():.2g} lower)",
        )
        return state
    trial, pred, rj, chi2_new, tail = jump(vals, free, chi2, gain, ripe, run)
    if not chi2_new < chi2:  # includes a run that failed (inf)
        at = trial[free][ripe].min()
        rank0(logger, fm.comm, f"  fit: {names} at {at:.3g}: chi2 not lower; going on")
        fm.set_values(vals)
        return state
    r, Jr = rj
    if tail:
        watch.hold(ripe, tail_gain(trial[free], Jr, r))
    rank0(
        logger,
        fm.comm,
        f"  fit: {names} ran towards infinity; at {trial[free][ripe].min():.3g} chi2 = "
        f"{chi2_new:.6g} ({chi2 - chi2_new:.3g} lower)"
        + (
            ": held at this stiff limit (the data do not bound it above; at infinity chi2 "
            f"would be {watch.left[ripe].sum():.2g} lower)"
            if tail
            else ", not as a stiff tail would: the fit goes on"
        ),
    )
    return trial, pred, r, Jr, chi2_new
