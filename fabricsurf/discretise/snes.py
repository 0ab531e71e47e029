"""PETSc's SNES as :class:`~fabricsurf.discretise.solver.SNESSolver` uses it: the options it
starts from (:data:`SNES_DEFAULTS`, and :data:`DOMAIN_AWARE` for energies with a restricted
domain), the keys of ``options`` that it reads itself rather than PETSc (:data:`SOLVER_KEYS`:
the Jacobian, the compile mode, the Newton-correction test), and the converged reasons SNES
answers with, in words (for messages and logs).
"""

from __future__ import annotations

from petsc4py import PETSc

SNES_DEFAULTS: dict[str, object] = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-10,
    "snes_stol": 1e-14,
    "snes_max_it": 25,
    "snes_divergence_tolerance": 1e8,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
}
DOMAIN_AWARE: dict[str, object] = {"snes_linesearch_type": "bt", "snes_max_it": 50}
"""Options for energies with a restricted domain: the backtracking line search shrinks a Newton
step that leaves the domain (or does not decrease the residual) instead of failing."""

STEP_RTOL = 1e-8
"""A solve that met only the relative residual test (``snes_rtol``) is accepted once a Newton
correction is below this fraction of the state's norm (``snes_stol`` for the continued solve,
:meth:`~fabricsurf.discretise.solver.SNESSolver.solve`)."""

SOLVER_KEYS = ("jacobian", "compile", "step_rtol")
"""Keys of ``options`` read by :class:`~fabricsurf.discretise.solver.SNESSolver` itself, not by
PETSc: ``jacobian`` = ``"given"`` (the form passed in, default) or ``"exact"`` (the derivative
of the residual form, ``ufl.derivative``: quadratic Newton convergence, one more form to
compile); ``compile`` = ``"optimised"`` (dolfinx's JIT defaults, -O2) or ``"fast"`` (-O0: the
large kernels of the full 3D model compile about three times faster and run slower, for meshes
so small that compiling dominates, as in the exact-solution checks); ``step_rtol`` (default
:data:`STEP_RTOL`; 0 turns the check off): the Newton-correction test of
:meth:`~fabricsurf.discretise.solver.SNESSolver.solve`."""
COMPILE_ARGS = {"optimised": None, "fast": ["-O0", "-g0"]}


def jit_params(mode: str) -> dict:
    """dolfinx's JIT parameters for a ``compile`` mode of :data:`SOLVER_KEYS`."""
    if mode not in COMPILE_ARGS:
        raise ValueError(f"compile = {mode!r}: must be one of {list(COMPILE_ARGS)}")
    args = COMPILE_ARGS[mode]
    return {} if args is None else {"cffi_extra_compile_args": args}


def apply_options(snes: PETSc.SNES, prefix: str, options: dict) -> None:
    """Apply PETSc options (over :data:`SNES_DEFAULTS`) to ``snes`` and its KSP under
    ``prefix``; the global database is left as it was found (entries set here are removed,
    entries that were there before, e.g. from the command line, restored)."""
    opts = PETSc.Options()
    merged = {**SNES_DEFAULTS, **options}
    before = {k: opts.getString(prefix + k) for k in merged if opts.hasName(prefix + k)}
    try:
        for k, v in merged.items():
            opts[prefix + k] = v
        snes.setOptionsPrefix(prefix)
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
    finally:
        for k in merged:
            opts.delValue(prefix + k)
            if k in before:
                opts[prefix + k] = before[k]


RELATIVE = int(PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE)
"""The reason of a solve accepted by the relative residual test alone (``snes_rtol``)."""


def _reason_names() -> dict[int, str]:
    R = PETSc.SNES.ConvergedReason
    names = {getattr(R, k): k for k in dir(R) if k.isupper() and k != "ITERATING"}
    names[0] = "CONVERGED_ITERATING"
    return names


SNES_REASONS = _reason_names()


def reason_name(reason: int) -> str:
    """PETSc's SNESConvergedReason code in words, e.g. −5 → 'DIVERGED_MAX_IT (-5)'."""
    return f"{SNES_REASONS.get(int(reason), 'UNKNOWN')} ({int(reason)})"
