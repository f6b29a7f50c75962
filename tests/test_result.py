"""Tests of hybrid_force.result: the Result schema, atomic save/load, and run metrics."""

from __future__ import annotations

import io
import json
import math
import os
import re
import struct
import time
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hybrid_force.errors import BadInputError
from hybrid_force.metrics import Metrics
from hybrid_force.result import Result, load_result
from hybrid_force.result_file import ARRAY_NAMES, MAX_META_DEPTH, _json_depth

SCHEMA_NAMES = {
    "t", "q", "v", "q_d", "u", "p", "p_d", "f", "f_d", "phi", "V", "phase", "f_meas", "u_cmd",
    "law_log",
}  # fmt: skip


def _meta(**extra: Any) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "name": "unit",
        "scenario": None,
        "robot": {"model": "rtr", "tip": "tip", "nq": 3},
        "surfaces": [
            {
                "type": "cylinder",
                "radius": 0.4,
                "center": [0, 0, 0],
                "axis": [0, 0, 1],
                "inside": False,
            }
        ],
        "path": {"type": "helix", "center": [0, 0, 10], "radius": 0.4, "axis": [0, 0, 1]},
        "gains": {"Kd": [1.0, 2.0, 3.0], "Lambda": 5.0, "beta": 1.0, "gamma": 2.0, "f_d": 10.0},
        "settings": {"dt": 0.001, "duration": 1.0, "integrator": "euler", "settle_time": 0.5},
        "events": [{"t": 0.25, "kind": "contact"}, {"t": 0.25, "kind": "impact", "impulse": 0.1}],
        "status": "ok",
        "error": None,
        "versions": {"hybrid_force": "0.1.0", "pinocchio": "4.1.0", "numpy": np.__version__},
        "steps_per_second": 12345.5,
        "wall_time": 0.8,
        "unicode": "Φ λ × · −",
    }
    meta.update(extra)
    return meta


def _random_arrays(
    rng: np.random.Generator, n_samples: int = 50, n: int = 3, k: int = 1, nq: int | None = None
) -> dict[str, np.ndarray]:
    nq = n if nq is None else nq
    cshape: tuple[int, ...] = (n_samples,) if k == 1 else (n_samples, k)
    return {
        "t": np.cumsum(rng.uniform(0.001, 0.01, n_samples)),
        "q": rng.standard_normal((n_samples, nq)),
        "v": rng.standard_normal((n_samples, n)),
        "q_d": rng.standard_normal((n_samples, nq)),
        "u": rng.standard_normal((n_samples, n)),
        "p": rng.standard_normal((n_samples, 3)),
        "p_d": rng.standard_normal((n_samples, 3)),
        "f": rng.standard_normal(cshape),
        "f_d": rng.standard_normal(cshape),
        "phi": rng.standard_normal(cshape) * 1e-9,
        "V": rng.uniform(0.0, 5.0, n_samples),
        "phase": rng.integers(0, 3, n_samples).astype(np.int64),
    }


def _random_result(seed: int = 0, **kw: Any) -> Result:
    return Result(**_random_arrays(np.random.default_rng(seed), **kw), meta=_meta())


# --------------------------------------------------------------------------- round trip
@pytest.mark.parametrize(
    "shape_kw",
    [{}, {"k": 2}, {"n": 2, "nq": 4}, {"n_samples": 1}, {"n_samples": 0}],
    ids=["k1", "k2", "nq>nv", "one-sample", "empty"],
)
def test_round_trip_preserves_every_array_and_meta(tmp_path: Path, shape_kw: dict) -> None:
    rng = np.random.default_rng(11)
    arrays = _random_arrays(rng, **shape_kw)
    res = Result(**arrays, meta=_meta())
    out = res.save(tmp_path / "run.npz")
    assert out == tmp_path / "run.npz"
    back = Result.load(out)
    for name in ARRAY_NAMES:
        a, b = arrays[name], getattr(back, name)
        assert b.dtype == (np.int64 if name == "phase" else np.float64), name
        assert b.shape == a.shape, name
        assert np.array_equal(a, b), name
    assert back.meta == _meta()
    assert back.n_samples == arrays["t"].shape[0]
    assert back.n_joints == arrays["v"].shape[1]
    assert back.nq == arrays["q"].shape[1]
    assert back.n_constraints == shape_kw.get("k", 1)
    again = load_result(out)
    assert np.array_equal(again.q, arrays["q"])


def test_round_trip_preserves_special_float_values(tmp_path: Path) -> None:
    arrays = _random_arrays(np.random.default_rng(3), n_samples=6)
    arrays["V"][:] = [np.nan, np.inf, -np.inf, -0.0, 5e-324, 1.7976931348623157e308]
    back = Result.load(Result(**arrays, meta=_meta()).save(tmp_path / "x.npz"))
    assert np.array_equal(back.V, arrays["V"], equal_nan=True)
    assert np.signbit(back.V[3])


def test_saved_file_has_exactly_the_schema_arrays_and_no_pickle(tmp_path: Path) -> None:
    path = _random_result(5).save(tmp_path / "r.npz")
    with np.load(path, allow_pickle=False) as npz:
        assert set(npz.files) == SCHEMA_NAMES | {"meta"}
        meta = npz["meta"]
        assert meta.shape == () and meta.dtype.kind == "U"
        assert json.loads(str(meta)) == _meta()
        for name in SCHEMA_NAMES:
            assert npz[name].dtype != object
    with zipfile.ZipFile(path) as zf:
        assert sorted(zf.namelist()) == sorted(f"{n}.npy" for n in SCHEMA_NAMES | {"meta"})


def test_save_creates_parent_directory_and_overwrites(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b" / "run.npz"
    _random_result(1).save(target)
    second = _random_result(2)
    second.save(target)
    assert np.array_equal(Result.load(target).q, second.q)
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.npz"]
    other = tmp_path / "plain" / "run.result"  # the name is used as given, no suffix added
    assert second.save(other) == other and other.is_file()
    assert np.array_equal(load_result(other).v, second.v)


def test_save_into_a_directory_path_is_rejected(tmp_path: Path) -> None:
    with pytest.raises(BadInputError, match=str(tmp_path)):
        _random_result().save(tmp_path)


# --------------------------------------------------------------------------- atomic save
def _write_partial_then_interrupt(file: Any, *args: Any, **kwargs: Any) -> None:
    file.write(b"PK\x03\x04 half an archive")
    raise KeyboardInterrupt


def test_interrupted_savez_keeps_old_file_and_removes_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "run.npz"
    old = _random_result(1)
    old.save(target)
    before = target.read_bytes()
    monkeypatch.setattr(np, "savez", _write_partial_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        _random_result(2).save(target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]
    monkeypatch.undo()
    assert np.array_equal(Result.load(target).u, old.u)


def test_interrupted_replace_keeps_old_file_and_removes_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "run.npz"
    _random_result(1).save(target)
    before = target.read_bytes()
    seen: list[Path] = []

    def interrupted_replace(src: str, dst: Any) -> None:
        src_path = Path(src)
        seen.append(src_path)
        # the temporary file is complete, in the target's directory, and not the target
        assert src_path.parent == target.parent and src_path != target
        with np.load(src_path, allow_pickle=False) as npz:
            assert set(npz.files) == SCHEMA_NAMES | {"meta"}
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted_replace)
    with pytest.raises(KeyboardInterrupt):
        _random_result(2).save(target)
    assert len(seen) == 1 and not seen[0].exists()
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["run.npz"]


def test_failed_first_save_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def disk_full(*args: Any, **kwargs: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", disk_full)
    with pytest.raises(OSError, match=r"No space"):
        _random_result().save(tmp_path / "new.npz")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- bad files
def _good_file(tmp_path: Path) -> Path:
    return _random_result(7).save(tmp_path / "good.npz")


def _rewrite(path: Path, arrays: dict[str, np.ndarray]) -> None:
    with path.open("wb") as fh:
        np.savez(fh, **arrays)


def _contents(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nope.npz"
    with pytest.raises(BadInputError, match=r"nope.npz.*does not exist"):
        Result.load(path)


def test_truncated_file(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(BadInputError, match=r"good.npz") as info:
        Result.load(path)
    assert isinstance(info.value, BadInputError)


@pytest.mark.parametrize(
    "content", [b"this is a text file\nnot a result\n", b"", b"PK\x03\x04garbage"]
)
def test_garbage_file(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "junk.npz"
    path.write_bytes(content)
    with pytest.raises(BadInputError, match=r"junk.npz"):
        load_result(path)


def test_npy_instead_of_npz(tmp_path: Path) -> None:
    path = tmp_path / "single.npy"
    np.save(path, np.arange(3.0))
    with pytest.raises(BadInputError, match=r"single.npy.*single numpy array"):
        Result.load(path)


def test_npz_missing_arrays_lists_them(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    arrays = _contents(path)
    del arrays["phi"]
    del arrays["V"]
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz") as info:
        Result.load(path)
    msg = str(info.value)
    assert "phi" in msg and "V" in msg
    assert msg.index("missing") < msg.index("phi")


def test_bad_meta_json(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    arrays = _contents(path)
    arrays["meta"] = np.array('{"name": "x", ')
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz.*meta.*JSON"):
        Result.load(path)
    arrays["meta"] = np.array("[1, 2]")
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz.*JSON object"):
        Result.load(path)
    arrays["meta"] = np.array([1.0, 2.0])
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz.*meta"):
        Result.load(path)


def test_inconsistent_shapes_in_file(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    arrays = _contents(path)
    arrays["u"] = arrays["u"][:-1]
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz.*'u'.*\(50, 3\).*\(49, 3\)"):
        Result.load(path)


def test_wrong_dtype_in_file(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    arrays = _contents(path)
    arrays["phase"] = arrays["phase"].astype(float)
    _rewrite(path, arrays)
    with pytest.raises(BadInputError, match=r"good.npz.*phase"):
        Result.load(path)


def test_object_array_in_file_is_refused(tmp_path: Path) -> None:
    path = _good_file(tmp_path)
    arrays: dict[str, Any] = _contents(path)
    arrays["q"] = np.array([{"a": 1}], dtype=object)
    with path.open("wb") as fh:
        np.savez(fh, allow_pickle=True, **arrays)
    with pytest.raises(BadInputError, match=r"good.npz"):
        Result.load(path)


# --------------------------------------------------------------------------- validation
def test_construction_shape_errors_name_array_and_shapes() -> None:
    rng = np.random.default_rng(2)
    cases = {
        "q_d": (np.zeros((50, 4)), r"'q_d'.*\(50, 3\).*\(50, 4\)"),
        "p": (np.zeros((50, 2)), r"'p'.*\(50, 3\).*\(50, 2\)"),
        "V": (np.zeros(49), r"'V'.*\(50,\).*\(49,\)"),
        "phase": (np.zeros((50, 1), dtype=np.int64), r"'phase'.*\(50,\).*\(50, 1\)"),
        "f_d": (np.zeros((50, 2)), r"'f_d'.*\(50,\).*\(50, 2\)"),
        "t": (np.zeros((50, 1)), r"'t'.*\(N,\).*\(50, 1\)"),
        "v": (np.zeros((50, 4)), r"'v'.*\(50, 4\)"),
    }
    for name, (bad, pattern) in cases.items():
        arrays = _random_arrays(rng)
        arrays[name] = bad
        with pytest.raises(BadInputError, match=pattern):
            Result(**arrays, meta=_meta())


def test_single_constraint_must_be_flat() -> None:
    arrays = _random_arrays(np.random.default_rng(4))
    for name in ("f", "f_d", "phi"):
        arrays[name] = arrays[name][:, None]
    with pytest.raises(BadInputError, match=r"'f'.*\(50,\).*\(50, 1\)"):
        Result(**arrays, meta=_meta())


def test_value_and_dtype_errors() -> None:
    rng = np.random.default_rng(6)
    arrays = _random_arrays(rng)
    arrays["phase"][3] = 5
    with pytest.raises(BadInputError, match=r"phase.*5.*sample 3"):
        Result(**arrays)
    arrays = _random_arrays(rng)
    arrays["phase"] = arrays["phase"].astype(float)
    with pytest.raises(BadInputError, match=r"phase.*int"):
        Result(**arrays)
    arrays = _random_arrays(rng)
    arrays["u"] = arrays["u"].astype(complex)
    with pytest.raises(BadInputError, match=r"'u'.*complex"):
        Result(**arrays)
    arrays = _random_arrays(rng)
    arrays["t"][10] = arrays["t"][9]
    with pytest.raises(BadInputError, match=r"strictly increasing.*t\[9\]"):
        Result(**arrays)
    with pytest.raises(BadInputError, match=r"status.*'done'.*ok, failed"):
        Result(**_random_arrays(rng), meta={"status": "done"})
    with pytest.raises(BadInputError, match=r"JSON"):
        Result(**_random_arrays(rng), meta={"x": object()})
    with pytest.raises(BadInputError, match=r"NaN"):
        Result(**_random_arrays(rng), meta={"x": float("nan")})
    with pytest.raises(BadInputError, match=r"events"):
        Result(**_random_arrays(rng), meta={"events": [{"kind": "impact"}]})


def test_arrays_are_copied_converted_and_read_only() -> None:
    arrays = _random_arrays(np.random.default_rng(8))
    arrays["q"] = np.arange(150).reshape(50, 3)  # int -> float64
    res = Result(**arrays, meta={"steps": np.int64(3), "vec": np.arange(2.0), "tup": (1, 2)})
    assert res.q.dtype == np.float64 and np.array_equal(res.q, np.arange(150).reshape(50, 3))
    assert res.meta == {"steps": 3, "vec": [0.0, 1.0], "tup": [1, 2]}
    arrays["v"][0, 0] = 123.0
    assert res.v[0, 0] != 123.0
    with pytest.raises(ValueError, match=r"read-only"):
        res.p[0, 0] = 1.0
    assert res.status == "ok" and not res.failed and res.events == []
    failed = res.with_meta(status="failed", error="diverged at t=0.1")
    assert failed.failed and failed.meta["error"] == "diverged at t=0.1" and not res.failed


def test_truncated_and_slice() -> None:
    arrays = _random_arrays(np.random.default_rng(9))
    res = Result(**arrays, meta=_meta(status="failed"))
    part = res.truncated(20)
    assert part.n_samples == 20 and part.failed
    for name in ARRAY_NAMES:
        assert np.array_equal(getattr(part, name), arrays[name][:20])
    assert res.slice(7).n_samples == 7 and res.truncated(0).n_samples == 0
    assert res.truncated(50).n_samples == 50
    for bad in (-1, 51, 2.5):
        with pytest.raises(BadInputError, match=r"\[0, 50\]|int"):
            res.truncated(bad)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- metrics
DT = 1.0 / 64.0  # exact binary step, so t = 1.0 and t = 2.0 fall on samples
N = 193  # t = 0 .. 3 s


def _synthetic(events: list[dict] | None = None) -> Result:
    """Hand-built run: known errors, phases, forces, drift and events (see test)."""
    t = np.arange(N) * DT
    p_d = np.stack([np.sin(t), np.cos(t), 0.1 * t], axis=1)
    e = np.zeros((N, 3))
    e[t < 1.0, 0] = 0.05  # 50 mm on x before t = 1
    e[t >= 1.0, 0] = 0.002  # constant 2 mm on x from t = 1
    e[128, 2] = 0.003  # one 3 mm spike on z at t = 2
    e[20, 1] = -0.06  # one -60 mm spike on y before settling
    phase = np.zeros(N, dtype=np.int64)
    phase[32:40] = 1  # near from t = 0.5
    phase[40:160] = 2  # contact from t = 0.625
    phase[160:170] = 0  # released
    phase[170:] = 2  # contact again
    f_d = np.full(N, 10.0)
    f = np.where(phase == 2, 10.0 + 0.5 * t, 0.0)  # error ramp 0.5 t in contact, 10 N outside
    phi = np.where(phase == 2, 1e-10, 0.2)
    phi[100] = -4e-9  # worst drift in contact
    phi[165] = 0.5  # large, but not in contact
    n = 3
    meta = _meta(
        events=events if events is not None else [],
        settings={"dt": DT, "duration": 3.0, "integrator": "euler", "settle_time": 1.0},
    )
    return Result(
        t=t,
        q=np.zeros((N, n)),
        v=np.zeros((N, n)),
        q_d=np.zeros((N, n)),
        u=np.zeros((N, n)),
        p=p_d + e,
        p_d=p_d,
        f=f,
        f_d=f_d,
        phi=phi,
        V=np.zeros(N),
        phase=phase,
        meta=meta,
    )


def test_metrics_position_errors_by_hand() -> None:
    m = _synthetic().metrics()  # settle_time from meta: 1.0 s -> samples 64..192 (129 of them)
    assert m.settle_time == 1.0
    assert m.position_error_max_axis == pytest.approx((0.002, 0.0, 0.003), abs=1e-15)
    assert m.position_error_rms_axis == pytest.approx(
        (0.002, 0.0, math.sqrt(0.003**2 / 129)), rel=1e-12, abs=1e-15
    )
    assert m.position_error_max == pytest.approx(math.hypot(0.05, 0.06), rel=1e-12)
    assert m.position_error_max_settled == pytest.approx(math.hypot(0.002, 0.003), rel=1e-12)
    rms_norm = math.sqrt((128 * 0.002**2 + (0.002**2 + 0.003**2)) / 129)
    assert m.position_error_rms_settled == pytest.approx(rms_norm, rel=1e-12)
    assert m.final_position_error == pytest.approx(0.002, rel=1e-12)
    assert m.time_to_converge is None  # 2 mm never goes below 1 mm


def test_metrics_time_to_converge_by_hand() -> None:
    res = _synthetic()
    # 2.5 mm: the 3.6 mm spike at sample 128 is the last one above -> converged at sample 129
    assert res.metrics(converge_tolerance=2.5e-3).time_to_converge == pytest.approx(129 * DT)
    # 40 mm: everything from t = 1 is below; the 50 mm before is above -> t = 1.0
    assert res.metrics(converge_tolerance=0.04).time_to_converge == pytest.approx(1.0)
    # 1 m: always below -> first sample
    assert res.metrics(converge_tolerance=1.0).time_to_converge == 0.0
    with pytest.raises(BadInputError, match=r"converge_tolerance"):
        res.metrics(converge_tolerance=-1.0)


def test_metrics_force_and_contact_by_hand() -> None:
    m = _synthetic().metrics()
    contact_settled = [i for i in range(64, N) if i < 160 or i >= 170]
    errs = [0.5 * (i * DT) for i in contact_settled]
    assert m.force_error_max_settled == pytest.approx(0.5 * 3.0, rel=1e-12)
    rms = math.sqrt(sum(x * x for x in errs) / len(errs))
    assert m.force_error_rms_settled == pytest.approx(rms, rel=1e-12)
    assert m.final_force_error == pytest.approx(1.5, rel=1e-12)
    assert m.worst_constraint_violation == pytest.approx(4e-9, rel=1e-12)
    assert m.contact_time == pytest.approx(40 * DT)  # first phase-2 sample, no events
    assert m.impact_impulse == 0.0 and m.impact_speed is None and m.n_impacts == 0


def test_metrics_settle_time_override_and_default() -> None:
    res = _synthetic()
    m = res.metrics(settle_time=2.5)  # samples 160..192: contact only from 170
    assert m.force_error_max_settled == pytest.approx(1.5, rel=1e-12)
    assert m.position_error_max_axis == pytest.approx((0.002, 0.0, 0.0), abs=1e-15)
    no_settings = res.with_meta(settings={})
    m5 = no_settings.metrics()  # default 5 s is after the run: settled metrics do not apply
    assert m5.settle_time == 5.0
    assert m5.position_error_max_axis is None and m5.position_error_rms_settled is None
    assert m5.force_error_max_settled is None and m5.force_error_rms_settled is None
    assert m5.final_position_error == pytest.approx(0.002, rel=1e-12)


def test_metrics_events_preferred_and_impacts_summed() -> None:
    events = [
        {"t": 0.5, "kind": "near"},
        {"t": 0.62, "kind": "contact"},
        {"t": 0.62, "kind": "impact", "impulse": 0.3, "speed": 0.25},
        {"t": 2.6, "kind": "release"},
        {"t": 2.65, "kind": "contact"},
        {"t": 2.65, "kind": "impact", "impulse": -0.2, "speed": -0.1},
        {"t": 2.7, "kind": "branch", "impulse": 9.0, "speed": 9.0},
    ]
    res = _synthetic(events)
    m = res.metrics()
    assert m.contact_time == pytest.approx(0.62)
    assert m.impact_impulse == pytest.approx(0.5, rel=1e-12)
    assert m.impact_speed == pytest.approx(0.25)
    assert m.n_impacts == 2
    s = res.summary()
    assert s["n_events"] == 7 and s["name"] == "unit" and s["status"] == "ok"
    assert s["steps_per_second"] == 12345.5
    assert s["impact_impulse"] == pytest.approx(0.5)
    json.dumps(s, allow_nan=False)


def test_metrics_when_run_ends_out_of_contact_or_never_touches() -> None:
    res = _synthetic()
    m = res.truncated(165).metrics()  # last sample (164) is free
    assert m.final_force_error is None
    assert m.force_error_max_settled == pytest.approx(0.5 * 159 * DT, rel=1e-12)
    free = Result(
        **{
            name: (np.zeros(N, np.int64) if name == "phase" else getattr(res, name))
            for name in ARRAY_NAMES
        },
        meta=res.meta,
    )
    m = free.metrics()
    assert m.contact_time is None and m.worst_constraint_violation is None
    assert m.force_error_max_settled is None and m.final_force_error is None
    d = m.to_dict()
    assert isinstance(d["position_error_max_axis"], list)
    assert "NaN" not in json.dumps(d)
    assert json.loads(json.dumps(d, allow_nan=False)) == d


def test_metrics_skip_non_finite_samples_of_a_diverged_run() -> None:
    res = _synthetic()
    p = np.array(res.p)
    p[-1, 0] = np.nan
    f = np.array(res.f)
    f[-1] = np.inf
    bad = Result(
        **{name: getattr(res, name) for name in ARRAY_NAMES if name not in ("p", "f")},
        p=p,
        f=f,
        meta=_meta(status="failed", settings={"settle_time": 1.0}),
    )
    m = bad.metrics(converge_tolerance=2.5e-3)
    assert m.final_position_error is None and m.final_force_error is None
    assert m.time_to_converge is None  # a NaN at the end is not "below tolerance"
    assert m.position_error_max_settled == pytest.approx(math.hypot(0.002, 0.003), rel=1e-12)
    assert m.force_error_max_settled == pytest.approx(0.5 * 191 * DT, rel=1e-12)
    json.dumps(m.to_dict(), allow_nan=False)


def test_metrics_with_two_constraints_use_the_force_error_norm() -> None:
    n_s = 4
    t = np.arange(n_s) * 0.5
    f = np.tile([13.0, 24.0], (n_s, 1))
    f_d = np.tile([10.0, 20.0], (n_s, 1))
    phi = np.array([[1e-9, -3e-9], [0.0, 0.0], [2e-9, 1e-9], [0.0, -1e-9]])
    res = Result(
        t=t,
        q=np.zeros((n_s, 2)),
        v=np.zeros((n_s, 2)),
        q_d=np.zeros((n_s, 2)),
        u=np.zeros((n_s, 2)),
        p=np.zeros((n_s, 3)),
        p_d=np.zeros((n_s, 3)),
        f=f,
        f_d=f_d,
        phi=phi,
        V=np.zeros(n_s),
        phase=np.full(n_s, 2, np.int64),
    )
    m = res.metrics(settle_time=0.0)
    assert res.n_constraints == 2
    assert m.force_error_max_settled == pytest.approx(5.0)  # |(3, 4)| = 5
    assert m.force_error_rms_settled == pytest.approx(5.0)
    assert m.worst_constraint_violation == pytest.approx(3e-9)
    assert m.time_to_converge == 0.0 and m.contact_time == 0.0


def test_metrics_is_a_frozen_dataclass() -> None:
    m = _synthetic().metrics()
    assert isinstance(m, Metrics)
    with pytest.raises(AttributeError):
        m.contact_time = 1.0  # type: ignore[misc]


# --------------------------------------------------------------------------- bounded resources
# Crafted archives must be refused with a BadInputError naming the file, before anything
# large is allocated or decompressed; through the CLI: exit 2 and one 'error:' line.
def _npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    """A version 1.0 .npy header claiming ``shape`` of ``descr`` (no data)."""
    from numpy.lib import format as npy_format

    buf = io.BytesIO()
    npy_format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _replace_member(src: Path, dst: Path, old: str, new: str, data: bytes) -> Path:
    """Copy the archive ``src`` to ``dst`` with member ``old`` replaced by ``new`` = data."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            if info.filename == old:
                zout.writestr(new, data)
            else:
                zout.writestr(info, zin.read(info))
    return dst


def _crafted_header_file(tmp_path: Path) -> Path:
    """A genuine result whose t.npy claims shape (10**12,) float64 (8 TB) but holds 16 bytes."""
    return _replace_member(
        _good_file(tmp_path),
        tmp_path / "crafted.npz",
        "t.npy",
        "t.npy",
        _npy_header((10**12,)) + b"\0" * 16,
    )


def _patch_zip_headers(
    data: bytes, local: tuple[int, str, int], central: tuple[int, str, int]
) -> bytes:
    """Set a field (offset, struct format, value) in every local and central zip header."""
    out = bytearray(data)
    for sig, (offset, fmt, value) in ((b"PK\x03\x04", local), (b"PK\x01\x02", central)):
        i = out.find(sig)
        while i >= 0:
            struct.pack_into(fmt, out, i + offset, value)
            i = out.find(sig, i + 4)
    return bytes(out)


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str]:
    """Run hybrid_force.cli.main(argv); return (status, the single stderr line)."""
    from hybrid_force.cli import main

    capsys.readouterr()
    status = main(list(argv))
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return status, lines[0]


def _refuse_np_load(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Make np.load (as hybrid_force.result calls it) record and refuse any call."""
    import hybrid_force.result as result_module

    calls: list[Any] = []

    def no_load(*args: Any, **kwargs: Any) -> Any:
        calls.append(args)
        raise AssertionError("np.load reached: the archive was not refused before loading")

    monkeypatch.setattr(result_module.np, "load", no_load)
    return calls


def test_npy_header_claiming_terabytes_is_refused_before_numpy_allocates(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _crafted_header_file(tmp_path)
    calls = _refuse_np_load(monkeypatch)
    with pytest.raises(BadInputError) as info:
        Result.load(path)
    msg = str(info.value)
    assert str(path) in msg and "'t'" in msg and "(1000000000000,)" in msg
    assert "8000000000000 bytes" in msg and "holds 144 bytes" in msg
    assert calls == []


def test_npy_header_claiming_terabytes_through_plot_and_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _crafted_header_file(tmp_path)
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line and "claims shape" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crafted.npz", "good.npz"]
    html = tmp_path / "x.html"
    status, line = _cli(capsys, "replay", str(path), "--html", str(html))
    assert status == 2 and str(path) in line and "claims shape" in line
    assert not html.exists()


def test_declared_sizes_beyond_available_memory_are_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import hybrid_force.result_file as result_file

    path = _good_file(tmp_path)
    assert Result.load(path).n_samples == 50  # a genuine result, loadable with real memory
    monkeypatch.setattr(result_file, "available_memory", lambda: None)  # unknown: not checked
    assert Result.load(path).n_samples == 50
    monkeypatch.setattr(result_file, "available_memory", lambda: 1000)
    with pytest.raises(BadInputError) as info:
        Result.load(path)
    msg = str(info.value)
    assert str(path) in msg and "decompressed" in msg and "memory is available" in msg
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line and "memory is available" in line


def test_deflated_zip_bomb_is_refused_before_decompression(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import hybrid_force.result_file as result_file

    n = 4 << 20  # 32 MiB of float64 zeros, deflated to a few tens of kB
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("t.npy", _npy_header((n,)) + bytes(8 * n))
    assert path.stat().st_size < 200_000
    monkeypatch.setattr(result_file, "available_memory", lambda: 1 << 20)  # 1 MiB free
    calls = _refuse_np_load(monkeypatch)
    opened: list[Any] = []

    def no_open(self: zipfile.ZipFile, name: Any, *args: Any, **kwargs: Any) -> Any:
        opened.append(name)
        raise AssertionError(f"member {name!r} decompressed before the size check")

    monkeypatch.setattr(zipfile.ZipFile, "open", no_open)
    start = time.perf_counter()
    with pytest.raises(BadInputError) as info:
        Result.load(path)
    elapsed = time.perf_counter() - start
    assert str(path) in str(info.value) and "memory is available" in str(info.value)
    assert calls == [] and opened == []
    assert elapsed < 2.0, elapsed


def test_member_whose_declared_size_understates_its_content_is_refused(tmp_path: Path) -> None:
    # the zip directory says 208 bytes (header + 10 float64); the deflated data holds 8 MiB more
    header = _npy_header((10,))
    path = tmp_path / "liar.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("t.npy", header + bytes(80) + bytes(8 << 20))
    size = len(header) + 80
    path.write_bytes(_patch_zip_headers(path.read_bytes(), (22, "<I", size), (24, "<I", size)))
    with zipfile.ZipFile(path) as zf:
        assert zf.getinfo("t.npy").file_size == size
    with pytest.raises(BadInputError, match=re.escape(str(path))):
        Result.load(path)


def test_archive_with_a_thousand_members_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "many.npz"
    with zipfile.ZipFile(path, "w") as zf:
        for i in range(1000):
            zf.writestr(f"a{i}.npy", _npy_header((1,)) + bytes(8))
    calls = _refuse_np_load(monkeypatch)
    with pytest.raises(BadInputError) as info:
        Result.load(path)
    assert str(path) in str(info.value) and "1000 members" in str(info.value)
    assert calls == []


def _with_meta_text(tmp_path: Path, text: str) -> Path:
    path = _good_file(tmp_path)
    arrays = _contents(path)
    arrays["meta"] = np.array(text)
    _rewrite(path, arrays)
    return path


@pytest.mark.parametrize(
    "text",
    [
        "[" * 100_000 + "]" * 100_000,
        '{"a": ' * 100_000 + "1" + "}" * 100_000,
        '{"name": "x", "deep": ' + "[" * 69 + "]" * 69 + "}",  # 70 levels
        "[" * 70 + "]" * 70,
        '{"a": ' * 65 + "{}" + "}" * 65,  # 66 levels
    ],
    ids=["lists-100000", "objects-100000", "70-in-object", "lists-70", "objects-66"],
)
def test_meta_nested_too_deeply_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path = _with_meta_text(tmp_path, text)
    with pytest.raises(BadInputError) as info:
        Result.load(path)
    msg = str(info.value)
    assert str(path) in msg and f"more than {MAX_META_DEPTH} levels" in msg
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line and "nested" in line


def test_meta_nesting_up_to_the_limit_loads(tmp_path: Path) -> None:
    deep: Any = 1
    for _ in range(MAX_META_DEPTH - 1):
        deep = [deep]
    path = _with_meta_text(tmp_path, json.dumps({"name": "x", "deep": deep}))  # 64 levels
    assert _json_depth(Result.load(path).meta) == MAX_META_DEPTH
    path = _with_meta_text(tmp_path, json.dumps({"name": "x", "deep": [deep]}))  # 65 levels
    with pytest.raises(BadInputError, match=r"nested more than 64"):
        Result.load(path)


def test_npy_file_given_instead_of_npz_through_the_cli(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "single.npz"  # an .npy file under a result's name
    with path.open("wb") as fh:
        np.save(fh, np.arange(10**5, dtype=float))
    with pytest.raises(BadInputError, match=r"single numpy array"):
        Result.load(path)
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line and "single numpy array" in line
    status, line = _cli(capsys, "replay", str(path), "--html", str(tmp_path / "x.html"))
    assert status == 2 and str(path) in line and "single numpy array" in line
    assert not (tmp_path / "x.html").exists()


def test_npy_header_in_member_without_npy_suffix_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # 2**57 float64 = 1 EiB: beyond any address space, so allocating it fails everywhere
    path = _replace_member(
        _good_file(tmp_path),
        tmp_path / "nosuffix.npz",
        "t.npy",
        "t",
        _npy_header((2**57,)) + b"\0" * 16,
    )
    with pytest.raises(BadInputError, match=re.escape(str(path))):
        Result.load(path)
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line


@pytest.mark.parametrize(
    ("local", "central"),
    [((6, "<H", 1), (8, "<H", 1)), ((8, "<H", 99), (10, "<H", 99))],
    ids=["encrypted-flag", "compression-method-99"],
)
def test_unsupported_zip_member_is_refused(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    local: tuple[int, str, int],
    central: tuple[int, str, int],
) -> None:
    path = _good_file(tmp_path)
    path.write_bytes(_patch_zip_headers(path.read_bytes(), local, central))
    with pytest.raises(BadInputError, match=re.escape(str(path))):
        Result.load(path)
    status, line = _cli(capsys, "plot", str(path))
    assert status == 2 and str(path) in line


def test_a_file_without_the_measured_force_loads_with_the_true_one(tmp_path: Path) -> None:
    """Files written before f_meas existed: the controller then measured the plant's force."""
    path = _good_file(tmp_path)
    arrays = _contents(path)
    arrays.pop("f_meas", None)
    _rewrite(path, arrays)
    result = Result.load(path)
    np.testing.assert_array_equal(result.f_meas, result.f)


def test_a_measured_force_of_the_wrong_shape_is_refused() -> None:
    base = _random_result(5)
    with pytest.raises(BadInputError, match="f_meas"):
        Result(**{n: getattr(base, n) for n in ARRAY_NAMES}, f_meas=np.zeros(4))
