"""Stability regions of every kernel integrator, computed from the kernel's own stepping code.

1. Regions in the z = h*lambda plane: the spectral radius of the step matrix that the kernel's
   step routine applies to y' = lambda*y (2 x 2 real form; companion form for bdf2..bdf6;
   euler_cromer on the oscillator whose roots are z and conj z). All regions in one figure and
   each alone; the table gives the real-axis interval (a, 0) to 10 digits and, for the implicit
   methods, A-stability or the A(alpha) angle, with the CPU time each took.
2. The second-order view for mechanisms: the damped oscillator q'' + 2 zeta omega q' + omega^2 q
   in the (h omega, zeta) plane, and spectral radius, numerical damping and period error
   against h/T (T = 2 pi/omega).
3. Stability in practice: the largest step each method tolerates over 100 s (20 s with --quick)
   on the book's pendulum, damped oscillator and trolley crane, by bisection on the compiled
   nonlinear model, next to the predictions of its linearisation at rest (bounded for ever:
   rho <= 1; bounded over the run: rho^N <= 10).
4. The book's stability statements (4.18), (4.22), (4.29) and its two claims about
   Euler-Cromer, beside the computed values, with the errors explained.
5. The index-3 integrators of the generalized-alpha family (trapezoidal_index3, newmark, hht,
   generalized_alpha at several rho_inf): spectral radius, numerical damping ratio and period
   error against Omega = omega h, measured from the compiled steps on the undamped oscillator
   (mbdk.spectral: the kernel's runs of a body on a coordinate spring, their linear recurrence
   fitted by Prony's method) beside the closed forms of mbdk.alpha_family (Chung and Hulbert
   1993; Hughes 9.3), their largest difference, the high-frequency limit against the published
   rho_inf ((1 + alpha)/(1 - alpha) for HHT), the CPU time of the measurement, and the cost of
   a step on the double pendulum relative to trapezoidal_index3's, measured in one run.
6. Every fixed-step method on M q'' + K q = 0 (the ODE methods of sections 1-2 and the index-3
   family of section 5), the same three quantities over methods x Omega measured the same way
   from scene runs of the kernel's time loop, each beside its closed form (mbdk.oscillator_forms:
   Taylor polynomials, Pade approximants, Euler-Cromer's matrix, BDF's rho - i Omega sigma from
   Hairer, Norsett and Wanner's backward differences; mbdk.alpha_family), with the CPU time of
   the row's runs; a figure of spectral radius and period error against Omega. Then the
   pendulum (a point mass on a distance constraint) under the index-3 family in both
   formulations: its free direction at Omega = sqrt(g/l) h against the oscillator's closed
   form, its multiplier's oscillation (the square of the free direction's root), and its
   constrained direction, driven through the rod's length, whose transient roots are those of
   mbdk.alpha_family.constrained_amplification in the book form and absent in the projected
   one.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk import stability as S  # noqa: E402
from mbdk.analysis import plotting  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402

METHODS = list(mbdk.methods("ode", step="fixed"))
COLORS = {m: c for m, c in zip(METHODS, [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
    "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#393b79", "#637939"])}
PROBLEMS = ["pendulum", "damped_oscillator", "trolley_crane"]


def _fmt_a(a: float) -> str:
    return "-inf" if a == -math.inf else f"{a:.10f}"


def regions(out: Path, quick: bool):
    import matplotlib.pyplot as plt
    n = 161 if quick else 401
    regs = {}
    for m in METHODS:
        progress(f"region of {m}")
        regs[m] = S.stability_region(m, n=n)
    rows = []
    for m, r in regs.items():
        info = mbdk.methods()[m]
        osc = S.oscillator_limit(m, 0.0)
        rows.append({
            "method": m, "order": info.order,
            "real_interval_a": _fmt_a(r.real_interval[0]),
            "A_stable": "" if r.a_stable is None else ("yes" if r.a_stable else "no"),
            "A_alpha_deg": "" if r.alpha_deg is None else f"{r.alpha_deg:.7f}",
            "undamped_oscillator_h_omega_max": "inf" if osc == math.inf else f"{osc:.10f}",
            "test_system": r.definition, "cpu_s": r.cpu_time})
    cols = ["method", "order", "real_interval_a", "A_stable", "A_alpha_deg",
            "undamped_oscillator_h_omega_max", "test_system", "cpu_s"]
    table = write_table(rows, cols, out, "stability_intervals",
                        "Stability of every kernel method, computed from its step routine",
                        "real_interval_a: the method is stable on [a, 0] of the real axis "
                        "(z = h lambda). A_alpha_deg: the sector |arg(-z)| < alpha is stable. "
                        "undamped_oscillator_h_omega_max: largest h*omega with spectral radius "
                        "<= 1 on q'' + omega^2 q = 0 (0: unstable for every h > 0; heun's "
                        "rho - 1 = (h omega)^4/8 and bdf3's are tiny but positive). "
                        "cpu_s: CPU time of the region, interval and angle computations.")

    # all regions: explicit and implicit in two panels (their scales differ)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    for m, r in regs.items():
        ax = axes[1] if mbdk.methods()[m].implicit else axes[0]
        for k, b in enumerate(r.boundary):
            ax.plot(b.real, b.imag, color=COLORS[m], lw=1.3, label=m if k == 0 else None)
    for ax, title in zip(axes, ["explicit methods and Euler-Cromer (stable inside)",
                                "implicit methods (stable outside the curves, for bdf3-6 "
                                "also left of them)"]):
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
        ax.set_aspect("equal")
        ax.set_xlabel("Re z")
        ax.set_ylabel("Im z")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="upper left")
    total = sum(r.cpu_time for r in regs.values())
    fig.suptitle(f"Boundaries |rho| = 1 from the kernel's step matrices ({total:.2f} s CPU)")
    f_all = plotting.save(fig, out, "stability_regions_all")

    fig, axes = plt.subplots(3, 4, figsize=(15, 11))
    for ax, (m, r) in zip(axes.ravel(), regs.items()):
        ax.contourf(r.x, r.y, r.stable.astype(float), levels=[0.5, 1.5], colors=[COLORS[m]],
                    alpha=0.35)
        for b in r.boundary:
            ax.plot(b.real, b.imag, color=COLORS[m], lw=1)
        ax.axhline(0, color="k", lw=0.4)
        ax.axvline(0, color="k", lw=0.4)
        a = r.real_interval[0]
        sub = f"a = {_fmt_a(a)}"
        if r.alpha_deg is not None:
            sub += f", alpha = {r.alpha_deg:.4f} deg"
        ax.set_title(f"{m}\n{sub}\n({r.cpu_time:.2f} s CPU)", fontsize=8)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    fig.suptitle("Stable set (shaded) of each method in the z = h lambda plane")
    fig.tight_layout()
    f_each = plotting.save(fig, out, "stability_regions_each")
    return regs, rows, table, [f_all, f_each]


def oscillator(out: Path, quick: bool):
    import matplotlib.pyplot as plt
    t0 = time.process_time()
    hw = np.linspace(0.01, 6.0, 120 if quick else 300)
    zeta = np.linspace(0.0, 1.0, 41 if quick else 101)
    fig, axes = plt.subplots(3, 4, figsize=(15, 10), layout="constrained")
    for ax, m in zip(axes.ravel(), METHODS):
        rho = S.oscillator_map(m, hw, zeta)
        cs = ax.contourf(hw, zeta, np.minimum(rho, 1.5), levels=np.linspace(0, 1.5, 16),
                         cmap="viridis")
        ax.contour(hw, zeta, rho, levels=[1 + S.STABLE_TOL], colors="r", linewidths=1.2)
        ax.set_title(m, fontsize=9)
        ax.set_xlabel("h omega", fontsize=8)
        ax.set_ylabel("zeta", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.colorbar(cs, ax=axes, shrink=0.6, label="spectral radius (capped at 1.5); red: rho = 1")
    fig.suptitle("Damped oscillator: spectral radius of one step in the (h omega, zeta) plane "
                 f"({time.process_time() - t0:.2f} s CPU)")
    f_map = plotting.save(fig, out, "oscillator_map")

    t0 = time.process_time()
    hT = np.linspace(0.002, 0.5, 100 if quick else 250)
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    rows = []
    for m in METHODS:
        resp = S.oscillator_response(m, hT, 0.0)
        axes[0].plot(hT, resp.spectral_radius, color=COLORS[m], label=m)
        axes[1].plot(hT, resp.numerical_damping, color=COLORS[m], label=m)
        axes[2].plot(hT, resp.period_error, color=COLORS[m], label=m)
        for target in (0.01, 0.05, 0.1):
            r1 = S.oscillator_response(m, [target], 0.0)
            rows.append({"method": m, "h_over_T": target, "spectral_radius":
                         float(r1.spectral_radius[0]), "numerical_damping_ratio":
                         float(r1.numerical_damping[0]), "period_error":
                         float(r1.period_error[0])})
    axes[0].set_ylim(0.0, 1.6)
    axes[0].set_ylabel("spectral radius")
    axes[1].set_ylim(-0.3, 0.6)
    axes[1].set_ylabel("numerical damping ratio (negative: growth)")
    axes[2].set_ylim(-0.5, 1.0)
    axes[2].set_ylabel("relative period error  T_num/T - 1")
    for ax in axes:
        ax.set_xlabel("h / T")
        ax.axhline(0 if ax is not axes[0] else 1, color="k", lw=0.5)
    axes[2].legend(fontsize=7, ncol=2)
    fig.suptitle("Undamped oscillator (zeta = 0) against h/T, from the kernel's step matrices "
                 f"({time.process_time() - t0:.2f} s CPU)")
    f_curves = plotting.save(fig, out, "oscillator_curves")
    table = write_table(rows, ["method", "h_over_T", "spectral_radius",
                               "numerical_damping_ratio", "period_error"], out,
                        "oscillator_accuracy",
                        "Undamped oscillator: numerical damping and period error at h/T = "
                        "0.01, 0.05, 0.1",
                        "numerical_damping_ratio = -Re(log mu)/|log mu| of the principal root mu "
                        "(positive: the method damps; negative: it amplifies); period_error = "
                        "discrete period / exact - 1 (positive: the method lags). The principal "
                        "root is the eigenvalue nearest exp(h lambda); the jumps of the bdf "
                        "curves in oscillator_curves.png at large h/T are where another root "
                        "becomes the nearest.")
    return table, [f_map, f_curves]


def practice(out: Path, quick: bool):
    import matplotlib.pyplot as plt
    t_span = 20.0 if quick else 100.0
    methods = METHODS if not quick else ["explicit_euler", "heun", "rk4", "euler_cromer",
                                         "trapezoidal", "bdf4"]
    rows = []
    for p in PROBLEMS:
        y_eq, jac = S.linearisation(p)
        for m in methods:
            progress(f"largest step: {p} / {m}")
            lim = S.largest_stable_step(p, m, t_span=t_span, growth=10.0, h_cap=1.0)
            forever, horizon = S.linear_step_limits(m, jac, t_span=t_span, growth=10.0, h_cap=1.0)
            ratio = lim.h / horizon if horizon > 0 else None
            rows.append({"problem": p, "method": m, "t_span_s": t_span,
                         "h_max_nonlinear": lim.h, "h_fail": lim.h_fail, "reason": lim.reason,
                         "h_linear_forever": forever, "h_linear_over_run": horizon,
                         "nonlinear_over_linear": ratio, "solves": lim.solves,
                         "cpu_s": lim.cpu_time})
    cols = ["problem", "method", "t_span_s", "h_max_nonlinear", "h_fail", "reason",
            "h_linear_forever", "h_linear_over_run", "nonlinear_over_linear", "solves", "cpu_s"]
    table = write_table(
        rows, cols, out, "stability_in_practice",
        f"Largest step over {t_span:g} s on the nonlinear models against the linearised prediction",
        "h_max_nonlinear: the largest h found stable (bisection to 0.1 %, capped at h = 1): the run "
        "stays finite, Newton converges, and every state stays within 10x its reference "
        "amplitude (max |y_i| of rk4 at h = 1e-3). h_fail: the nearest step that failed, and "
        "why. h_linear_forever: rho(step matrix of the linearisation at rest) <= 1 (0: "
        "unstable for every h, so only the run length bounds the step). h_linear_over_run: "
        "rho^N <= 10 over the same run. cpu_s: the kernel CPU time of all the search's runs. "
        "trolley_crane uses the book's coefficients (coupling = -1); its rest state is "
        "phi = -90 deg.")

    fig, axes = plt.subplots(1, len(PROBLEMS), figsize=(15, 4.8))
    for ax, p in zip(axes, PROBLEMS):
        sub = [r for r in rows if r["problem"] == p]
        x = np.arange(len(sub))
        ax.bar(x - 0.2, [r["h_max_nonlinear"] for r in sub], 0.4, label="nonlinear run")
        ax.bar(x + 0.2, [r["h_linear_over_run"] for r in sub], 0.4, label="linearised, same run")
        ax.set_xticks(x)
        ax.set_xticklabels([r["method"] for r in sub], rotation=60, fontsize=7)
        ax.set_yscale("log")
        ax.set_ylabel("largest stable h (s)")
        cpu = sum(r["cpu_s"] for r in sub)
        ax.set_title(f"{p} ({cpu:.2f} s CPU)", fontsize=9)
        ax.legend(fontsize=7)
    fig.suptitle(f"Stability in practice over {t_span:g} s: nonlinear bisection against the "
                 "linear prediction (bars at 1 = the cap)")
    fig.tight_layout()
    return table, [plotting.save(fig, out, "stability_in_practice")]


def book_claims(out: Path, regs, intervals):
    by = {r["method"]: r for r in intervals}

    def row(eq, method, quantity, book, computed, verdict, note, cpu):
        return {"equation": eq, "method": method, "quantity": quantity, "book": book,
                "computed": computed, "verdict": verdict, "note": note, "cpu_s": cpu}

    e, h, rk4 = regs["explicit_euler"], regs["heun"], regs["rk4"]
    ec, ie = regs["euler_cromer"], regs["implicit_euler"]
    rows = [
        row("(4.18)", "explicit_euler", "stable h on y' = -y", "h < 2",
            f"h <= {-e.real_interval[0]:.10f}", "agrees",
            "the conclusion is right; the printed condition |1 - h| < 2 is not (it would allow "
            "h < 3): the condition is |R| = |1 - h| <= 1", e.cpu_time),
        row("(4.22)", "implicit_euler", "stability", "unconditionally stable",
            f"A-stable (alpha = {ie.alpha_deg:g} deg), real interval (-inf, 0]", "agrees",
            "R(z) = 1/(1 - z): |R| < 1 in the whole left half-plane", ie.cpu_time),
        row("(4.29)", "heun", "stable h on y' = -y", "h < 0.73205",
            f"h <= {-h.real_interval[0]:.10f}", "FLAG",
            "R(z) = 1 + z + z^2/2 gives 1 - h + h^2/2 on y' = -y; the book's k2 lost a sign "
            "(1 - h - h^2/2), and 0.73205 = sqrt(3) - 1 is the root of that wrong polynomial "
            "(where y1 = 0), not a stability limit: heun is stable up to h = 2",
            h.cpu_time),
        row("line 1921", "euler_cromer", "stability", "the same as RK2-4",
            f"undamped oscillator: h omega <= {by['euler_cromer']['undamped_oscillator_h_omega_max']}"
            f" (heun: {by['heun']['undamped_oscillator_h_omega_max']}, rk4: "
            f"{by['rk4']['undamped_oscillator_h_omega_max']}); real axis: a = "
            f"{_fmt_a(ec.real_interval[0])} (heun -2, rk4 {_fmt_a(rk4.real_interval[0])})",
            "FLAG",
            "not the same in either direction: on undamped oscillations Euler-Cromer keeps "
            "|mu| = 1 up to h omega = 2, where heun grows at every h and rk4 lasts to "
            "2 sqrt 2; on damped (real) modes its interval is less than half of theirs",
            ec.cpu_time + h.cpu_time + rk4.cpu_time),
        row("line 2260", "euler_cromer", "stability", "as stable as an implicit method",
            f"h omega <= {by['euler_cromer']['undamped_oscillator_h_omega_max']} on the undamped "
            f"oscillator; implicit_euler and trapezoidal: inf", "FLAG",
            "Euler-Cromer is explicit and only conditionally stable: beyond h omega = 2 its "
            "roots leave the unit circle (see stability_regions_each and oscillator_map). Its "
            "virtue is different: symplectic, so it neither damps nor amplifies below the limit",
            ec.cpu_time + ie.cpu_time),
    ]
    cols = ["equation", "method", "quantity", "book", "computed", "verdict", "note", "cpu_s"]
    return write_table(rows, cols, out, "stability_book_claims",
                       "The book's stability statements against the kernel",
                       "Fekete (2023) section 4.1; line numbers refer to the seed text. "
                       "cpu_s: CPU time of the computations behind 'computed'.")


#: the members of the generalized-alpha family in section 5: label, method, options
FAMILY = [("trapezoidal_index3", "trapezoidal_index3", {}),
          ("newmark gamma 0.6", "newmark", {"newmark_beta": 0.3025, "newmark_gamma": 0.6}),
          ("hht alpha -0.1", "hht", {"alpha_hht": -0.1}),
          ("hht alpha -1/3", "hht", {"alpha_hht": -1.0 / 3.0}),
          ("generalized_alpha rho 0.8", "generalized_alpha", {"rho_inf": 0.8}),
          ("generalized_alpha rho 0.5", "generalized_alpha", {"rho_inf": 0.5}),
          ("generalized_alpha rho 0", "generalized_alpha", {"rho_inf": 0.0})]


def _published_rho_inf(method: str, opts: dict) -> float:
    """The high-frequency spectral radius the literature gives: rho_inf by construction
    (Chung and Hulbert 1993), (1 + alpha)/(1 - alpha) for HHT (Hilber, Hughes and Taylor 1977),
    1 for the trapezoidal rule; NaN for Newmark (no value quoted here)."""
    if method == "generalized_alpha":
        return opts["rho_inf"]
    if method == "hht":
        a = opts["alpha_hht"]
        return (1 + a) / (1 - a)
    if method == "trapezoidal_index3":
        return 1.0
    return math.nan


def alpha_family(out: Path, quick: bool):
    """Section 5 (see the module docstring)."""
    import matplotlib.pyplot as plt
    from mbdk import alpha_family as AF, spectral
    omegas = np.geomspace(0.05, 100.0, 14 if quick else 40)
    rows, fig_rows = [], {}
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    for i, (label, method, opts) in enumerate(FAMILY):
        progress(f"spectrum of {label}")
        p = AF.parameters(method, **opts)
        t0 = time.process_time()
        meas = np.array([spectral.measured_properties(method, w, **opts)[:3] for w in omegas])
        cpu = time.process_time() - t0
        cf = np.array([AF.closed_form_properties(p, w) for w in omegas])
        # where one finds an oscillation and the other none, the difference is infinite
        both_nan = np.isnan(meas) & np.isnan(cf)
        d = np.where(both_nan, 0.0, np.abs(meas - cf))
        diff = np.where(np.isnan(d), np.inf, d).max(axis=0)
        rho_hi = spectral.measured_properties(method, 1e4, **opts)[0]
        for ax, k in zip(axes, range(3)):
            # one colour and marker per member for its measured dots and its closed form
            st = plotting.line_style(i)
            ax.semilogx(omegas, meas[:, k], st["marker"], color=st["color"], ms=4, mfc="none")
            ax.semilogx(omegas, cf[:, k], "-", lw=1, color=st["color"], marker=st["marker"],
                        mfc="none", markevery=[], label=label)
        for target in (0.1, 1.0):
            m1 = spectral.measured_properties(method, target, **opts)
            rows.append({"method": label, "Omega": target, "spectral_radius": m1[0],
                         "damping_ratio": m1[1], "period_error": m1[2],
                         "max_diff_closed_form": float(diff.max()),
                         "rho_at_Omega_1e4": rho_hi,
                         "published_rho_inf": _published_rho_inf(method, opts),
                         "cpu_s": cpu})
        fig_rows[label] = meas
    axes[0].set_ylabel("spectral radius")
    axes[1].set_ylabel("numerical damping ratio")
    axes[1].set_yscale("symlog", linthresh=1e-4)
    axes[2].set_ylabel("relative period error")
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xlabel("Omega = omega h")
    axes[0].legend(fontsize=7)
    fig.suptitle("The generalized-alpha family on the undamped oscillator: measured from the "
                 "compiled steps (dots) and the closed forms (lines)")
    f = plotting.save(fig, out, "alpha_family_spectra")
    # the cost of a step, relative to trapezoidal_index3's, on the double pendulum (one run)
    sc = mbdk.scene("double_pendulum")
    base = None
    for label, method, opts in FAMILY:
        r = mbdk.simulate(sc, method, h=1e-3, t_end=2.0, every=2000, outputs=(), **opts)
        per_step = r.stats.cpu_time / r.stats.steps
        base = base or per_step
        for row in rows:
            if row["method"] == label:
                row["cpu_per_step_vs_trapezoidal"] = per_step / base
                row["newton_per_step"] = r.stats.newton_iterations / r.stats.steps
    table = write_table(rows, ["method", "Omega", "spectral_radius", "damping_ratio",
                               "period_error", "max_diff_closed_form", "rho_at_Omega_1e4",
                               "published_rho_inf", "newton_per_step",
                               "cpu_per_step_vs_trapezoidal", "cpu_s"], out,
                        "alpha_family_spectra",
                        "The generalized-alpha family: spectral radius, damping and period "
                        "error from the compiled steps",
                        "Omega = omega h on q'' = -omega^2 q; measured: Prony's fit to the "
                        "kernel's steps (mbdk.spectral); max_diff_closed_form: the largest "
                        "difference of the three quantities from mbdk.alpha_family's closed "
                        "forms over Omega in [0.05, 100]; rho_at_Omega_1e4 against the "
                        "published high-frequency limit; cpu_per_step_vs_trapezoidal: the "
                        "solving thread's CPU time per step on the double pendulum (h = 1e-3, "
                        "2 s, augmented Lagrangian) over trapezoidal_index3's, in one run; "
                        "cpu_s: the measurement's CPU time")
    return table, [f]


#: every fixed-step method on M q'' + K q = 0 in section 6: label, method, options
SPECTRA = [(m, m, {}) for m in METHODS] + FAMILY
SPECTRA_OMEGAS = (0.1, 0.5, 1.0, 1.5, 2.5, 3.0, 10.0)
PENDULUM_OMEGAS = (0.1, 0.5, 1.0, 3.0)
#: the multiplier's oscillation is read where it is neither clustered with the static root at 1
#: (small Omega) nor aliased (2 arg lambda beyond pi: Omega beyond about pi/2)
MULTIPLIER_OMEGAS = (0.5, 1.0)


def _nan_diff(a, b) -> float:
    """|a - b|, 0 where both are NaN (no oscillation in either), inf where one is."""
    if math.isnan(a) and math.isnan(b):
        return 0.0
    d = abs(a - b)
    return math.inf if math.isnan(d) else d


def spectra(out: Path, quick: bool):
    """Section 6 (see the module docstring)."""
    import matplotlib.pyplot as plt
    from mbdk import alpha_family as AF, oscillator_forms as OF, spectral
    rows = []
    for label, method, opts in SPECTRA:
        progress(f"spectrum from scene runs: {label}")
        for w in SPECTRA_OMEGAS:
            m = spectral.measure(method, w, **opts)
            cf = spectral.closed_form(method, w, **opts)
            rho_rel = abs(m.spectral_radius - cf[0]) / cf[0]
            dom = OF.dominant(method, w) if method in OF.METHODS else ""
            rows.append({"method": label, "Omega": w,
                         "spectral_radius": m.spectral_radius, "spectral_radius_cf": cf[0],
                         "damping_ratio": m.damping_ratio, "damping_ratio_cf": cf[1],
                         "period_error": m.period_error, "period_error_cf": cf[2],
                         "max_diff": max(rho_rel, _nan_diff(m.damping_ratio, cf[1]),
                                         _nan_diff(m.period_error, cf[2])),
                         "root_set_distance": m.root_distance, "dominant_root": dom,
                         "steps": m.steps, "cpu_s": m.cpu_time})
    t_osc = write_table(
        rows, ["method", "Omega", "spectral_radius", "spectral_radius_cf", "damping_ratio",
               "damping_ratio_cf", "period_error", "period_error_cf", "max_diff",
               "root_set_distance", "dominant_root", "steps", "cpu_s"], out,
        "oscillator_spectra",
        "Every fixed-step method on q'' = -omega^2 q: measured from scene runs beside the "
        "closed forms",
        "Omega = omega h. Measured: Prony's fit to the kernel's runs of a body on a coordinate "
        "spring (mbdk.spectral; order 2k for a k-step method, whose BDF start-up excites its "
        "spurious roots); _cf: the closed forms (mbdk.oscillator_forms for the ODE methods, "
        "mbdk.alpha_family for the index-3 family). spectral_radius: the largest modulus of "
        "all roots; damping_ratio (negative: the step amplifies) and period_error (positive: "
        "the motion lags) of the principal root, the one that tends to exp(i Omega) as Omega "
        "-> 0, followed by continuation; nan where it is real (euler_cromer beyond Omega = 2). "
        "max_diff: the largest of the relative difference of the radius and the absolute "
        "differences of the other two. root_set_distance: the largest distance from a "
        "measured root to the nearest closed-form root and back (a spurious root of bdf5-6 "
        "barely excited at small Omega is fitted loosely; the principal root is not). "
        "dominant_root: which root sets the radius (bdf6's spurious root beyond Omega = 1). "
        "Beyond Omega = pi the samples of the exact motion alias too. cpu_s: the solving "
        "thread's CPU time of the row's runs.")

    omegas = np.geomspace(0.01, 100.0, 13 if quick else 33)
    fine = np.geomspace(0.01, 100.0, 400)
    fig, axes = plt.subplots(1, 2, figsize=(16, 6.5))
    cpu_fig = 0.0
    for i, (label, method, opts) in enumerate(SPECTRA):
        meas = [spectral.measure(method, w, **opts) for w in omegas]
        cpu_fig += sum(x.cpu_time for x in meas)
        cf = spectral.closed_form(method, fine, **opts)
        color, marker = plotting.line_style(i)["color"], plotting.line_style(i)["marker"]
        style = "-" if method in OF.METHODS else "--"
        # the legend shows line and marker together: one method, closed form and measurement
        axes[0].loglog(fine, cf[:, 0], style, color=color, lw=1.2, marker=marker, ms=4,
                       mfc="none", markevery=[], label=label)
        axes[0].loglog(omegas, [x.spectral_radius for x in meas], marker, color=color, ms=4,
                       mfc="none")
        axes[1].semilogx(fine, cf[:, 2], style, color=color, lw=1.2)
        axes[1].semilogx(omegas, [x.period_error for x in meas], marker, color=color, ms=4,
                         mfc="none")
    axes[0].set_ylim(1e-2, 10.0)
    axes[0].axhline(1.0, color="k", lw=0.5)
    axes[0].set_ylabel("spectral radius")
    axes[1].set_yscale("symlog", linthresh=1e-6)
    axes[1].set_ylim(-1.0, 100.0)
    axes[1].set_ylabel("relative period error (principal root)")
    for ax in axes:
        ax.set_xlabel("Omega = omega h")
        ax.axvline(math.pi, color="0.6", lw=0.5, ls=":")
    axes[0].legend(fontsize=7, ncol=2, loc="lower left")
    fig.suptitle("Every fixed-step method on q'' = -omega^2 q: closed forms (lines; dashed: the "
                 "index-3 family) and the kernel's scene runs (dots), "
                 f"{cpu_fig:.2f} s CPU in the runs")
    f_spec = plotting.save(fig, out, "spectra_vs_omega")

    prow, crow = [], []
    for label, method, opts in FAMILY:
        progress(f"pendulum: {label}")
        p = AF.parameters(method, **opts)
        for form in ("index3", "augmented_lagrangian"):
            for w in PENDULUM_OMEGAS:
                fr = spectral.pendulum_free_direction(method, w, formulation=form, **opts)
                cf = AF.closed_form_properties(p, w)
                row = {"method": label, "formulation": form, "Omega": w,
                       "spectral_radius": fr.spectral_radius, "spectral_radius_cf": cf[0],
                       "damping_ratio": fr.damping_ratio, "damping_ratio_cf": cf[1],
                       "period_error": fr.period_error, "period_error_cf": cf[2],
                       "max_diff": max(abs(fr.spectral_radius - cf[0]),
                                       _nan_diff(fr.damping_ratio, cf[1]),
                                       _nan_diff(fr.period_error, cf[2])),
                       "cpu_s": fr.cpu_time}
                if w in MULTIPLIER_OMEGAS:
                    ml = spectral.pendulum_multiplier(method, w, fr.principal,
                                                      formulation=form, **opts)
                    row.update({"multiplier_damping_ratio": ml.damping_ratio,
                                "multiplier_period_error": ml.period_error})
                    row["cpu_s"] += ml.cpu_time
                prow.append(row)
            c = spectral.pendulum_constrained_direction(method, formulation=form, **opts)
            cf_roots = AF.constrained_roots(p) if form == "index3" else np.zeros(0)
            cf_poly = (AF.constrained_polynomial(p) if form == "index3" else np.array([1.0]))
            rho_cf = float(np.abs(cf_roots).max()) if cf_roots.size else 0.0
            coef = (float(np.abs(c.quotient - cf_poly).max()) if c.quotient.size == cf_poly.size
                    else math.inf)
            growth = ""
            if cf_roots.size and rho_cf >= 1 - 1e-12:
                growth = "grows linearly (double root on the unit circle)"
            crow.append({"method": label, "formulation": form,
                         "roots": " ".join(f"{z.real:.6f}{z.imag:+.1e}j" for z in c.roots)
                         or "none",
                         "roots_cf": " ".join(f"{z.real:.6f}" for z in np.sort(cf_roots.real))
                         or "none",
                         "spectral_radius": c.spectral_radius, "spectral_radius_cf": rho_cf,
                         "damping_ratio_cf": (-math.log(rho_cf) / math.pi if 0 < rho_cf
                                              else math.inf),
                         "polynomial_diff": coef, "note": growth, "cpu_s": c.cpu_time})
    t_pend = write_table(
        prow, ["method", "formulation", "Omega", "spectral_radius", "spectral_radius_cf",
               "damping_ratio", "damping_ratio_cf", "period_error", "period_error_cf",
               "max_diff", "multiplier_damping_ratio", "multiplier_period_error", "cpu_s"],
        out, "pendulum_spectra",
        "The pendulum's free direction and multiplier under the index-3 family",
        f"A point mass on a distance constraint (l = {spectral.LENGTH:g} m, g = "
        f"{spectral.G:g} m/s^2), Omega = sqrt(g/l) h. Free direction: x_n of a swing of "
        f"{spectral.EPS_FREE:g} rad, fitted as the oscillator; _cf: the oscillator's closed "
        "form (mbdk.alpha_family): the constraint leaves them unchanged to the swing's "
        "O(eps^2) nonlinearity. multiplier_*: the multiplier's oscillation on a swing of "
        f"{spectral.EPS_MULTIPLIER:g} rad, read from its root nearest the square of the free "
        "direction's root, with its period against the exact 2 omega: the same damping ratio "
        "and period error as the free direction's (to the swing's O(eps^2)), read at Omega = "
        "0.5 and 1 only (smaller Omega clusters its roots at 1; larger aliases it). cpu_s: "
        "the row's runs.")
    t_con = write_table(
        crow, ["method", "formulation", "roots", "roots_cf", "spectral_radius",
               "spectral_radius_cf", "damping_ratio_cf", "polynomial_diff", "note", "cpu_s"],
        out, "constrained_direction_spectra",
        "The pendulum's constrained direction: the step's transient along the rod",
        "The bob hangs at rest and the rod's length follows l + A sin(omega_d t) (A = "
        f"{spectral.DRIVE_AMPLITUDE:g} m, omega_d = {spectral.DRIVE_OMEGA:g} rad/s, h = 0.1 s): "
        "the multiplier's fitted recurrence divided by the drive's factor leaves the step's "
        "transient along the constraint. roots_cf: mbdk.alpha_family.constrained_amplification "
        "(the relations with the constraint's coordinate held: -rho_inf three times for "
        "Chung-Hulbert's members, (1 + alpha)/(1 - alpha) twice and alpha/(1 + alpha) for HHT) "
        "in the book form (index3); none in the projected form, whose v, a and lambda are "
        "projected onto the constraints at every step. polynomial_diff: the largest "
        "difference of the measured and closed-form polynomials' coefficients (a triple root "
        "moves by the cube root of it, hence the radius' 1e-4). damping_ratio_cf: -ln(rho)/pi "
        "(negative real roots: a period of two steps). cpu_s: the run.")
    return [t_osc, t_pend, t_con], [f_spec]


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    regs, intervals, t1, f1 = regions(out, quick)
    progress("damped oscillator")
    t2, f2 = oscillator(out, quick)
    t3, f3 = practice(out, quick)
    t4 = book_claims(out, regs, intervals)
    t5, f5 = alpha_family(out, quick)
    t6, f6 = spectra(out, quick)
    figs = f1 + f2 + f3 + f5 + f6
    return {"title": "Stability regions and step limits, computed from the kernel's stepping code",
            "tables": [t1, t4, t2, t3, t5] + t6,
            "figures": [{"path": f, "caption": CAPTIONS.get(Path(f).stem, "")} for f in figs]}


#: what each figure shows and what to read from it, by file name
CAPTIONS = {
    "stability_regions_all": (
        "The boundary |rho| = 1 of every method's stable set in the plane z = h lambda, "
        "computed from the kernel's own step matrices. Read: a method is stable for a step h "
        "on y' = lambda y when h lambda lies inside its curve; the larger the region along the "
        "negative real axis, the larger the stable step on decaying modes, along the imaginary "
        "axis on oscillations."),
    "stability_regions_each": (
        "The same regions one method a panel, the stable set shaded. Read: implicit methods "
        "cover the whole left half-plane (A-stable) or a wedge of it; explicit ones a bounded "
        "patch whose extent on the real axis is the step limit in the book's tables."),
    "oscillator_map": (
        "The damped oscillator: the spectral radius of one step over the step h omega and the "
        "damping ratio zeta. Read: where the colour exceeds 1 the method amplifies (unstable "
        "there); the contour 1 is the step limit as a function of the damping."),
    "oscillator_curves": (
        "The undamped oscillator against h/T: spectral radius, numerical damping ratio and "
        "period error of one step. Read: a radius below 1 is numerical damping (energy "
        "lost), above 1 growth; the period error says how much the computed motion lags or "
        "leads per period."),
    "stability_in_practice": (
        "Per problem and method: the largest stable step found by bisection on nonlinear runs "
        "(left bar) beside the linearised prediction over the same run (right bar; log "
        "scale, bars at 1 are the search's cap). Read: where the two bars match, the linear "
        "theory of the regions predicts the nonlinear limit; where they differ, the "
        "nonlinearity sets it."),
    "alpha_family_spectra": (
        "The generalized-alpha family (Newmark, HHT, generalized-alpha at several rho_inf) on "
        "the undamped oscillator, measured from runs (markers) against the closed forms "
        "(lines). Read: at large Omega each curve levels at its rho_inf (the high-frequency "
        "damping it was chosen for); at small Omega the damping and the period error show what "
        "that damping costs in accuracy."),
    "spectra_vs_omega": (
        "Every fixed-step method on q'' = -omega^2 q: closed-form spectral radius and period "
        "error (lines; dashed: the index-3 family) against the kernel's runs (markers), over "
        "Omega = omega h. Read: markers on their line confirm the "
        "closed form; a radius above 1 marks the step limit; the dotted line is Omega = pi, "
        "beyond which samples alias."),
}


if __name__ == "__main__":
    raise SystemExit(main(run, "stability"))
