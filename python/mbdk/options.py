"""Options and statistics: the kernel's bind(C) structs, by name.

Each struct exists once, as a bind(C) type in Fortran; mbdk.h mirrors it as a C struct and this
module as a frozen dataclass. Across the f2py boundary a struct travels as its raw bytes (in
8-byte words), laid out with a numpy dtype built from the kernel's own table of names, offsets
and types (kernel/src/api/mbdk_structs.f90), so no field is read or written by array position.
tests/test_structs.py checks that the dataclasses, their defaults and the kernel agree, and
kernel/tests/c_struct_layout.c does the same for mbdk.h.

The `interrupt` field of the option structs is not mirrored here: the kernel call sets it to a
flag of its own (mbdk._compiled).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from . import _kernel
from .codes import FIELD_TYPES, STRUCT_IDS
from .errors import decode_text

_F64 = np.dtype(np.float64)


@lru_cache(maxsize=None)
def layout(cname: str) -> np.dtype:
    """The numpy dtype of a kernel struct, from the kernel's table (names, offsets, size)."""
    sid = STRUCT_IDS[cname]
    name, nbytes, nfields = _kernel.struct_info(sid)
    if decode_text(name) != cname or nfields < 1:
        raise RuntimeError(f"kernel struct {sid} is {decode_text(name)!r}, expected {cname!r}")
    names, formats, offsets = [], [], []
    for i in range(1, int(nfields) + 1):
        fname, offset, ftype = _kernel.struct_field(sid, i)
        names.append(decode_text(fname))
        formats.append(FIELD_TYPES[int(ftype)])
        offsets.append(int(offset))
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": int(nbytes)})


@lru_cache(maxsize=None)
def _default_words(cname: str) -> bytes:
    dt = layout(cname)
    return np.asarray(_kernel.struct_defaults(STRUCT_IDS[cname], dt.itemsize // 8)).tobytes()


@lru_cache(maxsize=None)
def _defaults(cname: str) -> tuple:
    """The kernel's default-initialised struct as Python numbers, in the layout's field order."""
    return np.frombuffer(_default_words(cname), dtype=layout(cname))[0].item()


@lru_cache(maxsize=None)
def _position(cname: str) -> dict:
    return {n: i for i, n in enumerate(layout(cname).names)}


def kernel_defaults(cname: str) -> dict:
    """The kernel's default-initialised struct, field by field."""
    return dict(zip(layout(cname).names, _defaults(cname)))


def pack(cname: str, values: dict) -> np.ndarray:
    """The struct's bytes, as 8-byte words for the f2py layer: the kernel's defaults with the
    given fields set by name (an unknown name is a KeyError). The record is built from one
    tuple: setting it field by field cost more than the rest of a short solve's Python."""
    where = _position(cname)
    fields_ = list(_defaults(cname))
    for k, v in values.items():
        i = where.get(k)
        if i is None:
            raise KeyError(f"{cname} has no field {k!r}")
        fields_[i] = v
    order, writer = _writer(cname)
    try:
        raw = writer.pack(*[fields_[i] for i in order])
    except struct.error:    # a value struct will not convert (a float in an integer field)
        return np.array([tuple(fields_)], dtype=layout(cname)).view(np.float64)
    return np.frombuffer(raw, dtype=np.float64).copy()


_STRUCT_CODES = {np.dtype(np.intc): "i", np.dtype(np.int64): "q", np.dtype(np.float64): "d",
                 np.dtype(np.uintp): "Q"}


@lru_cache(maxsize=None)
def _reader(cname: str):
    """(field names in offset order, a struct.Struct that reads the kernel's bytes into them):
    one C call, where a structured numpy view costs a Python-level safety check that is more
    than the rest of a short solve's result."""
    dt = layout(cname)
    fields_ = sorted((dt.fields[n][1], n, dt.fields[n][0]) for n in dt.names)
    fmt, at = "=", 0
    for offset, _, ftype in fields_:
        fmt += "x" * (offset - at) + _STRUCT_CODES[ftype]
        at = offset + ftype.itemsize
    fmt += "x" * (dt.itemsize - at)
    return tuple(n for _, n, _ in fields_), struct.Struct(fmt)


@lru_cache(maxsize=None)
def _writer(cname: str):
    """(the fields' indices in the layout's name order, taken in offset order; the
    struct.Struct that writes them as the kernel's bytes)."""
    names, reader = _reader(cname)
    where = _position(cname)
    return tuple(where[n] for n in names), reader


def unpack(cname: str, words) -> dict:
    names, reader = _reader(cname)
    if type(words) is not np.ndarray or words.dtype is not _F64:
        words = np.ascontiguousarray(words, dtype=np.float64)
    return dict(zip(names, reader.unpack(words.tobytes())))


def empty(cname: str) -> np.ndarray:
    """Zeroed words for a struct the kernel writes (statistics, a watch report)."""
    return np.zeros(layout(cname).itemsize // 8)


@lru_cache(maxsize=None)
def _field_names(cls) -> tuple:
    return tuple(f.name for f in fields(cls))


class _Struct:
    """Shared behaviour of the mirrors: their kernel struct's name and packing."""

    _cname = ""

    def pack(self) -> np.ndarray:
        # the fields are numbers: a shallow read (dataclasses.asdict deep-copies every value,
        # which cost more than the rest of a short solve's packing)
        return pack(self._cname, {n: getattr(self, n) for n in _field_names(type(self))})


@dataclass(frozen=True)
class ODEOptions(_Struct):
    """struct mbdk_options: an ODE solve (kernel/src/core/mbdk_options.f90)."""

    _cname = "mbdk_options"
    h: float = 0.0
    newton_rtol: float = 1e-10
    newton_atol: float = 1e-12
    rtol: float = 1e-6        # error-controlled methods
    atol: float = 1e-8
    dt_out: float = 0.0
    h_min: float = 0.0
    h_max: float = 0.0
    max_steps: int = 0        # 0 = 10^8
    method: int = 0
    every: int = 1
    newton_max_iter: int = 10
    fd_jacobian: int = 0
    nq: int = 0
    startup: int = 0          # 0 rk4 (the book), 1 bdf
    max_order: int = 0        # bdf, cvode_*: 0 = the method's highest


@dataclass(frozen=True)
class Index3Options(_Struct):
    """struct mbdk_index3_options: trapezoidal_index3 (kernel/src/dae/mbdk_trapezoidal_index3.f90)."""

    _cname = "mbdk_index3_options"
    h: float = 1e-3
    newton_rtol: float = 1e-10
    newton_atol: float = 1e-12
    alpha: float = 0.0
    err_rtol: float = 1e-6
    err_atol: float = 1e-8
    dt_out: float = 0.0
    h_min: float = 0.0
    h_max: float = 0.0
    formulation: int = 1      # 1 index3 (the book's scheme), 2 augmented_lagrangian
    every: int = 1
    newton_max_iter: int = 20
    adaptive: int = 0
    beta: float = 0.25        # the generalized-alpha family; the defaults: the trapezoidal rule
    gamma: float = 0.5
    alpha_m: float = 0.0
    alpha_f: float = 0.0


@dataclass(frozen=True)
class ModelOptions(_Struct):
    """struct mbdk_model_options: a scene model (kernel/src/model/mbdk_model.f90)."""

    _cname = "mbdk_model_options"
    baumgarte_alpha: float = 0.0
    baumgarte_beta: float = 0.0
    penalty_alpha: float = 1e7
    penalty_omega: float = 10.0
    penalty_mu: float = 1.0
    projection_tol: float = 1e-12
    formulation: int = 1      # 1 reduced, 2 baumgarte, 3 penalty, 4 projection
    solver: int = 1           # 1 auto, 2 schur, 3 kkt, 4 revolute_schur
    small_dense: int = 1
    projection_max_iter: int = 20
    watch_position: float = 1e-2   # what a run must keep (kernel/src/model/mbdk_watch.f90)
    watch_velocity: float = 1e-2
    watch_energy: float = 0.1
    watch_every: int = 16
    locate_events: int = 1   # dopri54, bs32: end a step where a contact closes or opens
    watch_momentum: float = 1e-2   # the momenta the scene conserves (mbdk_watch.f90)


@dataclass(frozen=True)
class SpatialOptions(_Struct):
    """struct mbdk_spatial_options: a spatial scene's model (kernel/src/spatial/
    mbdk_spatial_model.f90); the formulations' parameters carry ModelOptions' names."""

    _cname = "mbdk_spatial_options"
    baumgarte_alpha: float = 0.0
    baumgarte_beta: float = 0.0
    penalty_alpha: float = 1e7
    penalty_omega: float = 10.0
    penalty_mu: float = 1.0
    lock_guard: float = 0.0        # angle sets: MBDK_ERR_SINGULAR_MATRIX this near the lock
    norm_gain: float = 10.0        # the quaternion norm's stabilisation, 1/s
    projection_tol: float = 1e-12
    watch_position: float = 1e-2
    watch_velocity: float = 1e-2
    watch_energy: float = 0.1
    watch_momentum: float = 1e-2
    watch_quaternion: float = 0.1
    formulation: int = 1           # MBDK_FORM_*, as ModelOptions'
    rotation: int = 1              # 1 quaternion, 2 euler313, 3 cardan123
    norm: int = 1                  # 1 project, 2 stabilise, 3 none
    watch_every: int = 16
    locate_events: int = 1
    coordinates: int = 0           # 0 absolute, 1 joint (kernel/src/spatial/mbdk_joint_coords.f90)


#: the share of the smallest atol an error-controlled method's projection leaves in Phi when
#: projection_tol is not given: a multistep method (bdf) keeps the projection's move in its
#: history, and a leftover up to atol itself would enter its error estimate as noise of the
#: size of the tolerance (rejected steps down to StepTooSmallError); the kernel never goes
#: below its roundoff floor (a few eps times the mechanism's length)
PROJECTION_ATOL_SHARE = 1e-3


def projection_tol_for(given, atol=None) -> float:
    """The projection's tolerance on |Phi|: the one given; else ModelOptions' default, or for
    an error-controlled run with absolute tolerance atol (a number or array) a thousandth of
    its smallest entry where that is tighter."""
    if given is not None:
        return given
    tol = ModelOptions.projection_tol
    if atol is not None:
        tol = min(tol, PROJECTION_ATOL_SHARE * float(np.min(atol)))
    return tol


MIRRORS = {"mbdk_options": ODEOptions, "mbdk_index3_options": Index3Options,
           "mbdk_model_options": ModelOptions, "mbdk_spatial_options": SpatialOptions}


def field_names(cls) -> list[str]:
    return [f.name for f in fields(cls)]
