"""The method registry: names and ids come from the kernel (kernel/src/core/mbdk_methods.f90),
the properties a user compares methods by are stated here.
"""
from __future__ import annotations

from dataclasses import dataclass

from . import _kernel
from .checks import show
from .codes import METHOD_FAMILIES
from .errors import InvalidInputError, UnknownMethodError, decode_text


@dataclass(frozen=True)
class MethodInfo:
    name: str
    id: int
    family: str          # a value of mbdk.codes.METHOD_FAMILIES
    order: int
    implicit: bool
    steps: int           # previous values used (1 for one-step methods)
    stability: str
    reference: str

    @property
    def solves(self) -> str:
        """'ode': any y' = F(t, y), scenes through a formulation; 'dae': scenes only, their DAE
        itself (trapezoidal_index3: formulations index3 and augmented_lagrangian; ida: index1
        and ggl)."""
        return "dae" if self.family in ("dae_index3", "ida") else "ode"

    @property
    def adaptive(self) -> bool:
        """True: the step is chosen by error control (rtol, atol); False: a fixed step h."""
        return self.family in ("embedded_rk", "variable_bdf", "cvode", "ida")



_ABOUT = {
    "explicit_euler": ("conditionally stable: |1 + h*lambda| <= 1", "Fekete (2023) (4.6)"),
    "heun": ("conditionally stable: |1 + z + z^2/2| <= 1 (h < 2/|lambda| on the real axis)",
             "Fekete (2023) (4.23)"),
    "rk4": ("conditionally stable: real-axis limit h*|lambda| < 2.785", "Fekete (2023) (4.24)"),
    "euler_cromer": ("symplectic; stable for h*omega < 2 on oscillators", "Fekete (2023) (4.31)-(4.32); Cromer (1981)"),
    "implicit_euler": ("A-stable, L-stable", "Fekete (2023) (4.19)-(4.22)"),
    "trapezoidal": ("A-stable, not L-stable", "Fekete (2023) (3.12); Hairer-Wanner II"),
    "bdf1": ("A-stable, L-stable (same formula as implicit_euler)", "Gear (1971)"),
    "bdf2": ("A-stable", "Gear (1971)"),
    "bdf3": ("A(alpha)-stable, alpha = 86.03 deg", "Gear (1971)"),
    "bdf4": ("A(alpha)-stable, alpha = 73.35 deg", "Fekete (2023) (4.80); Gear (1971)"),
    "bdf5": ("A(alpha)-stable, alpha = 51.84 deg", "Gear (1971)"),
    "bdf6": ("A(alpha)-stable, alpha = 17.84 deg", "Gear (1971)"),
    "trapezoidal_index3": ("no numerical damping; the book's scheme is unstable in the "
                           "constrained directions, the augmented Lagrangian with projections "
                           "(ALI3-P) is not", "Fekete (2023) (3.11)-(3.16); Bayo and Ledesma "
                           "(1996)"),
    "newmark": ("unconditionally stable for 2 beta >= gamma >= 1/2; gamma > 1/2 damps high "
                "frequencies and is first order (the index-3 family, mbdk.alpha_family)",
                "Newmark (1959); Hughes, The Finite Element Method, ch. 9"),
    "hht": ("unconditionally stable, second order, high-frequency spectral radius (1 + alpha) / "
            "(1 - alpha) for alpha_hht in [-1/3, 0] (the index-3 family)",
            "Hilber, Hughes and Taylor (1977); Negrut et al. (2007) for HHT-I3"),
    "generalized_alpha": ("unconditionally stable, second order, high-frequency spectral "
                          "radius rho_inf in [0, 1] with the least low-frequency damping "
                          "(the index-3 family)", "Chung and Hulbert (1993); Arnold and "
                          "Bruls (2007); Bruls and Cardona (2010) on Lie groups"),
    "dopri54": ("conditionally stable (real-axis limit h*|lambda| < 3.31); error-controlled, "
                "dense output of order 4", "Dormand and Prince (1980); Shampine (1986); "
                "Hairer, Norsett and Wanner I, II.4-II.6"),
    "bs32": ("conditionally stable (real-axis limit h*|lambda| < 2.51); error-controlled, "
             "Hermite dense output", "Bogacki and Shampine (1989)"),
    "bdf": ("orders 1-2 A-stable, 3-5 A(alpha)-stable; variable step and order 1-5, "
            "error-controlled", "Gear (1971); Byrne and Hindmarsh (1975); Shampine and "
            "Reichelt (1997); MSC Adams' GSTIFF (the book, 4.4.2)"),
    "cvode_bdf": ("as bdf (SUNDIALS CVODE, BDF orders 1-5, Newton with a dense LU)",
                  "Hindmarsh et al. (2005), SUNDIALS"),
    "cvode_adams": ("conditionally stable (Adams-Moulton orders 1-12, fixed-point iteration): "
                    "for non-stiff problems", "Hindmarsh et al. (2005), SUNDIALS"),
    "ida": ("BDF orders 1-5 on the scene's DAE (SUNDIALS IDA): index 1, or stabilised index 2 "
            "(GGL); error test on q and v", "Hindmarsh et al. (2005); Gear, Gupta and "
            "Leimkuhler (1985)"),
}


def _load() -> dict[str, MethodInfo]:
    out = {}
    i = 1
    while True:
        name, family, order = _kernel.method_info(i)
        if family == 0:
            break
        name = decode_text(name)
        fam = METHOD_FAMILIES[int(family)]
        steps = int(name[3:]) if name[:3] == "bdf" and name[3:].isdigit() else 1
        stability, ref = _ABOUT[name]
        out[name] = MethodInfo(name, i, fam, int(order),
                               fam in ("implicit_lmm", "dae_index3", "variable_bdf", "cvode",
                                       "ida"),
                               steps, stability, ref)
        i += 1
    return out


_REGISTRY = _load()


def methods(solves: str | None = None, step: str | None = None) -> dict[str, MethodInfo]:
    """Every method, by name, with its properties; solves='ode' (what solve_ode and the scene
    formulations take) or 'dae' (trapezoidal_index3: scenes only) selects one kind, and
    step='fixed' (a step h) or 'adaptive' (error control by rtol and atol) another."""
    if solves is not None and (not isinstance(solves, str) or solves not in ("ode", "dae")):
        raise InvalidInputError(f"solves = {show(solves)} must be None, 'ode' or 'dae'")
    if step is not None and (not isinstance(step, str) or step not in ("fixed", "adaptive")):
        raise InvalidInputError(f"step = {show(step)} must be None, 'fixed' or 'adaptive'")
    return {k: m for k, m in _REGISTRY.items()
            if (solves is None or m.solves == solves)
            and (step is None or m.adaptive == (step == "adaptive"))}


def method(name: str) -> MethodInfo:
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise UnknownMethodError(
            f"unknown method {show(name)}; known methods: {', '.join(_REGISTRY)}") from None
