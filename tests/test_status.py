"""The status table exists once in Fortran and is mirrored in mbdk.h and in Python: they must
agree name by name (the C side is also checked by kernel/tests/c_status_table.c)."""
import re

from mbdk import Status, _kernel
from mbdk.errors import decode_text, exception_for


def kernel_table():
    out = {}
    i = 1
    while True:
        code, name, _msg = _kernel.status_entry(i)
        if code == 2**31 - 1:
            return out
        out[decode_text(name)] = int(code)
        i += 1


def header_table(root):
    text = (root / "kernel" / "include" / "mbdk.h").read_text()
    enum = re.search(r"enum mbdk_status \{(.*?)\};", text, re.S).group(1)
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"MBDK_(\w+)\s*=\s*(-?\d+)", enum)}


def test_fortran_c_python_agree(root):
    k = kernel_table()
    assert len(k) >= 13
    assert k == header_table(root)
    assert k == {s.name: s.value for s in Status}


def test_every_failure_has_a_named_exception_and_message():
    from mbdk import MbdkError
    from mbdk.errors import status_message
    for s in Status:
        assert status_message(s) != f"unknown status code {s.value}"
        if s.failed:
            cls = exception_for(s)
            if s == Status.ERR_INTERRUPTED:   # Ctrl-C stays a KeyboardInterrupt, not an Exception
                assert issubclass(cls, KeyboardInterrupt) and not issubclass(cls, Exception)
            else:
                assert issubclass(cls, MbdkError) and cls is not MbdkError
