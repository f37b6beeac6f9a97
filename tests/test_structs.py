"""Options and statistics exist once, as bind(C) types in the kernel; mbdk.h and the Python
dataclasses mirror them. The C side is checked by kernel/tests/c_struct_layout.c (offsets from
offsetof); here the Python side: the same fields in the same order, the same defaults, and a
round trip through the kernel's bytes that lands every field where the kernel reads it."""
import re

import numpy as np
import pytest

import mbdk
from mbdk import _kernel
from mbdk.options import MIRRORS, field_names, kernel_defaults, layout, pack, unpack


@pytest.mark.parametrize("cname", sorted(MIRRORS))
def test_option_dataclasses_mirror_the_kernel_structs(cname):
    cls = MIRRORS[cname]
    kernel = [n for n in layout(cname).names if n not in ("interrupt", "progress")]
    assert field_names(cls) == kernel
    d = kernel_defaults(cname)
    assert d.get("interrupt", 0) == 0      # no flag unless a caller sets one
    assert d.get("progress", 0) == 0
    assert {k: getattr(cls(), k) for k in kernel} == {k: d[k] for k in kernel}


def test_stats_dataclass_mirrors_the_kernel_struct():
    assert field_names(mbdk.Stats) == list(layout("mbdk_stats").names)
    assert kernel_defaults("mbdk_stats") == {k: 0 for k in layout("mbdk_stats").names}


def header_fields(text: str, cname: str) -> list[str]:
    body = re.search(r"typedef struct %s \{(.*?)\} %s;" % (cname, cname), text, re.S).group(1)
    body = re.sub(r"/\*.*?\*/", "", body, flags=re.S)
    names = []
    for decl in filter(None, (d.strip() for d in body.split(";"))):
        decl = re.sub(r"^(volatile\s+)?(int64_t|double|int)\s*\**", "", decl)
        names += [n.strip(" *") for n in decl.split(",")]
    return names


def test_header_structs_name_the_same_fields(root):
    """mbdk.h's typedefs list the kernel's field names in the kernel's order (the offsets are
    the C test's business)."""
    text = (root / "kernel" / "include" / "mbdk.h").read_text()
    for cname in ("mbdk_stats", "mbdk_options", "mbdk_index3_options", "mbdk_model_options",
                  "mbdk_spatial_options", "mbdk_watch_report"):
        assert header_fields(text, cname) == list(layout(cname).names), cname


def test_packed_options_reach_the_kernel_by_name():
    """Fields set by name arrive where the kernel reads them: a solve whose options say every=7
    and h=0.01 writes the samples at multiples of 0.07 and counts 4 evaluations per rk4 step."""
    words = pack("mbdk_options", {"h": 0.01, "every": 7, "method": mbdk.methods()["rk4"].id})
    back = unpack("mbdk_options", words)
    assert back["h"] == 0.01 and back["every"] == 7 and back["newton_max_iter"] == 10
    r = mbdk.solve_ode("damped_oscillator", "rk4", h=0.01, t_end=0.7, every=7)
    assert np.allclose(r.t, np.arange(0, 0.71, 0.07)) and r.stats.nfev == 4 * 70
    with pytest.raises(KeyError):
        pack("mbdk_options", {"hh": 1.0})


def test_a_struct_of_the_wrong_size_is_refused_by_the_kernel():
    sc = mbdk.scene("double_pendulum")
    tab = mbdk.model.build_tables(sc)
    short = mbdk.ModelOptions().pack()[:-1]
    *_, status = _kernel.model_eval(*tab.args(), short, tab.m, 0.0,
                                    np.concatenate([sc.q0(), sc.v0()]))
    assert status == mbdk.Status.ERR_INVALID_INPUT
