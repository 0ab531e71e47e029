"""Effects the vocabulary does not have: a search of the library of energy features
(:mod:`.features`, :mod:`.catalogue`) after a diagnosis (docs/diagnosis.md, "Beyond the
vocabulary").

:func:`search_beyond` takes a finished diagnosis and searches the features as the diagnosis
searches the named effects, with the same machinery: the final model and every feature (modulus
0) in one forward model, the features' linearised scores from the exact sensitivities (one
run), nested refits of the best ``confirm`` from the best of the usual starts, the significance
rule on each refit (Wald test on the cluster-robust covariance and the F-test against the
variance left), ties by Vuong's test (:mod:`.ties`); stepwise, up to ``max_features`` features.

Multiple testing: each feature is tested at the Bonferroni-corrected level (:mod:`.rule`).

It refits when the diagnosis leaves an excess it cannot explain, and when the final model is
adequate but one feature's linearised reduction comes near the corrected rule (the gate of
:mod:`.rule`: the adequacy test spreads its power over every residual, a feature's over one
direction). Not when the h/2 check says the mesh is too coarse: that excess is one a feature may
take up without any physics (forced on null data made at h = 2 mm and fitted at h = 4 mm, an
early −½k·min(λ−1,0)² feature took 45 % of the small excess the mesh left and passed the rule);
for the same reason the gate wants a reduction above the h/2 check's χ², and a feature must
stand on the h/2 check's residuals too (:mod:`.finer_mesh`, :mod:`.refine`). ``force=True``
searches anyway (calibration).

The outcome names what it found as a formula ("an energy ∝ γ²((λ−1)+(μ−1)) removes 61 % of the
excess; no named effect has this form"), with its share of the excess Δχ²/(χ² − ν), its modulus
and 95 % interval, where on the specimen its refit removes the misfit, and the Term source to
paste into a module of one's own; or "nothing beyond the vocabulary found".
"""

from fabricsurf.inverse.diagnosis.beyond.record import NOTHING, summary_lines
from fabricsurf.inverse.diagnosis.beyond.rule import family_alpha
from fabricsurf.inverse.diagnosis.beyond.search import search_beyond

__all__ = ["NOTHING", "family_alpha", "search_beyond", "summary_lines"]
