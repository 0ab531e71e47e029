"""C0-IP convergence on manufactured solutions of the nonlinear fabric energy
(docs/verification.md).

Theory for degree-2 C0 interior penalty on fourth-order problems (Brenner & Sung 2005;
Engel et al. 2002): broken-H2 error O(h), H1 and L2 errors O(h²) (for k = 2 duality gives no
extra order in L2). Asserted with a margin of 0.2 on the rate between the two finest meshes.
"""

from fabricsurf.verification.rates import rates
from research.verification.manufactured import in_plane_model, manufactured_solve, u_2d

THEORY = {"L2": 2.0, "H1": 2.0, "H2": 1.0}
MARGIN = 0.2
MESHES = (4, 8, 16)


def test_manufactured_convergence_rates():
    """The 2D case (all in-plane terms). The 3D case (all seven terms) compiles for minutes on a
    cold cache: it runs in benchmarks/convergence.py; in the suite the out-of-plane terms are
    checked by exact and independent solutions (hyperbolic paraboloid, cantilever vs elastica)."""
    d = 2
    errors = [manufactured_solve(in_plane_model(), u_2d, n, d)[0] for n in MESHES]
    hs = [1.0 / n for n in MESHES]
    for norm, expected in THEORY.items():
        r = rates([e[norm] for e in errors], hs)
        print(f"d = {d}: {norm} errors {[e[norm] for e in errors]}, rates {r}")
        assert r[-1] > expected - MARGIN, f"{norm} rate {r[-1]:.2f} below {expected} - {MARGIN}"


def test_penalty_insensitivity():
    """α ∈ [4, 64] changes the L2/H1 errors by < 25 % of those at α = 8, while one refinement
    changes them by a factor 4: the results are governed by h, not by the penalty."""
    model = in_plane_model()
    ref, _ = manufactured_solve(model, u_2d, 8, 2, penalty=8.0)
    for alpha in (4.0, 16.0, 64.0):
        e, _ = manufactured_solve(model, u_2d, 8, 2, penalty=alpha)
        for norm in ("L2", "H1"):
            ratio = e[norm] / ref[norm]
            print(f"alpha = {alpha}: {norm} error ratio to alpha = 8: {ratio:.3f}")
            assert 0.75 < ratio < 1.25
