"""Form cache keys do not depend on what was compiled before.

FFCx 0.5 marks an unmarked P1 coordinate element as equispaced, in place, while it analyses
the first form it compiles on a mesh (ffcx.analysis), and the mark enters the key (UFL
signature) of every later form on that mesh. Our meshes carry the mark from the start
(geometry.specimen.coordinate_domain, Problem's mark_equispaced), so a form's key is the same
whether earlier forms were compiled or read from the cache, and on every rank."""

import ffcx.analysis
import ffcx.parameters
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from fabricsurf.discretise.problem import mark_equispaced
from geometry.specimen import square

COMM = MPI.COMM_WORLD


def _key_before_and_after_analysis(msh) -> tuple[str, str]:
    """The signature of a form on ``msh`` before and after FFCx analyses another form there."""
    V = fem.VectorFunctionSpace(msh, ("CG", 2), dim=3)
    u = fem.Function(V)

    def form():
        return ufl.inner(ufl.grad(u), ufl.grad(u)) * ufl.dx

    before = form().signature()
    ffcx.analysis.analyze_ufl_objects([ufl.inner(u, u) * ufl.dx],
                                      ffcx.parameters.get_parameters())
    return before, form().signature()


def test_unmarked_mesh_changes_keys():
    """The FFCx behaviour the marking guards against: without it the key changes."""
    before, after = _key_before_and_after_analysis(dmesh.create_unit_square(COMM, 2, 2))
    assert before != after


def test_marked_meshes_keep_keys():
    """A gmsh-built specimen and a dolfinx mesh marked as Problem marks it keep their keys."""
    for msh in (square(1.0, 0.5, COMM).mesh, mark_equispaced(dmesh.create_unit_square(COMM, 2, 2))):
        before, after = _key_before_and_after_analysis(msh)
        assert before == after
