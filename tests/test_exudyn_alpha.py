"""benchmarks/exudyn_alpha.py, where Exudyn is installed (an optional peer: `pip install
exudyn`; without it these tests skip): the scenes it builds in Exudyn start in mbdk's state,
Exudyn's generalized-alpha parameters are Chung and Hulbert's from rho_inf (as its own printout
gives them), and on the double pendulum Exudyn's index-3 solver and mbdk's index3 form compute
the same discrete solution, while each differs from a dopri54 reference by its O(h^2) error."""
import sys

import numpy as np
import pytest

import mbdk

exu = pytest.importorskip("exudyn", reason="optional peer (pip install exudyn)")


@pytest.fixture(scope="module")
def bench(root):
    sys.path.insert(0, str(root / "benchmarks"))
    import exudyn_alpha
    return exudyn_alpha


@pytest.mark.parametrize("name", ["double_pendulum", "a02_n1", "flyball_governor"])
def test_the_exudyn_model_starts_in_mbdks_state(bench, name):
    sc = bench.case_scene(name)
    r0 = mbdk.simulate(sc, "generalized_alpha", h=1e-3, t_end=1e-3, outputs=())
    ex = bench.ExudynScene(sc, r0)
    assert np.max(np.abs(ex.state() - bench.mbdk_state(r0, 0))) < 1e-12


def test_exudyns_parameters_are_chung_hulberts(bench):
    """alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 - alpha_m +
    alpha_f, beta = (gamma + 1/2)^2 / 4, written out here, against Exudyn's printout (six
    digits)."""
    sc = mbdk.scene("double_pendulum")
    ex = bench.ExudynScene(sc, mbdk.simulate(sc, "generalized_alpha", h=1e-3, t_end=1e-3,
                                             outputs=()))
    for rho in (1.0, 0.8, 0.5, 0.3, 0.0):
        am, af = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
        g = 0.5 - am + af
        got = ex.parameters(rho)
        assert got == pytest.approx({"alpha_m": am, "alpha_f": af, "gamma": g,
                                     "beta": (g + 0.5) ** 2 / 4}, rel=1e-5, abs=1e-6)


def test_the_index3_form_is_exudyns_discrete_solution_on_the_double_pendulum(bench):
    sc = mbdk.scene("double_pendulum")
    t_end, h = 0.5, 1e-3
    ref, _, _ = bench.reference("double_pendulum", sc, t_end)
    r0 = mbdk.simulate(sc, "generalized_alpha", h=h, t_end=h, outputs=())
    ex = bench.ExudynScene(sc, r0)
    for rho in (0.8, 0.0):
        e = ex.run(rho, h, round(t_end / h), 1)["state"]
        m = bench.mbdk_run(sc, "index3", rho, h, t_end, 1)["state"]
        err = np.max(np.abs(m - ref))
        assert 1e-7 < err < 1e-3                        # a second-order error at h = 1e-3
        assert np.max(np.abs(e - ref)) == pytest.approx(err, rel=1e-2)
        assert np.max(np.abs(m - e)) < 1e-3 * err


def test_the_quick_table_has_cpu_time_and_a_verdict_on_every_row(bench, tmp_path):
    rows = bench.run(tmp_path, quick=True, repeats=1)
    assert rows and (tmp_path / "exudyn_alpha.csv").is_file()
    for r in rows:
        assert r["mbdk cpu us/step"] > 0 and r["Exudyn cpu us/step"] > 0, r
        assert r["cpu ratio mbdk/Exudyn"] == pytest.approx(
            r["mbdk cpu us/step"] / r["Exudyn cpu us/step"])
        assert r["agreement"] in ("same discrete solution", "to each method's accuracy") or \
            r["note"], r
