"""A law's own signals in a result (hybrid_force.law_log): recorded at every sample through the
optional Law hook, checked, saved and loaded, truncated with the run, and drawn."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import png_size

from hybrid_force.control.laws.base import check_log_source, law_log_names
from hybrid_force.errors import BadInputError, ControlError
from hybrid_force.result import Result
from hybrid_force.result_file import ARRAY_NAMES
from hybrid_force.run_output import RunOutput
from hybrid_force.scenario.loader import load_scenario
from hybrid_force.sim.loop import simulate
from hybrid_force.viz.figure_names import FIGURE_NAMES
from hybrid_force.viz.run_figures import plot_result

N = 40


def _result(law_log: np.ndarray | None = None, names: list[str] | None = None) -> Result:
    rng = np.random.default_rng(4)
    t = np.arange(N) * 0.01
    meta: dict = {"name": "logged", "status": "ok", "events": []}
    if names is not None:
        meta["law_log_names"] = names
    return Result(
        t=t, q=rng.standard_normal((N, 3)), v=rng.standard_normal((N, 3)),
        q_d=rng.standard_normal((N, 3)), u=rng.standard_normal((N, 3)),
        p=rng.standard_normal((N, 3)), p_d=rng.standard_normal((N, 3)),
        f=np.full(N, 10.0), f_d=np.full(N, 10.0), phi=np.zeros(N), V=np.exp(-t),
        phase=np.full(N, 2), meta=meta, law_log=law_log,
    )  # fmt: skip


def _estimates() -> tuple[np.ndarray, list[str]]:
    """Three signals: two decaying to 1.1× their start, one starting at 0."""
    t = np.arange(N) * 0.01
    grow = 1.1 - 0.1 * np.exp(-t)
    return np.column_stack([18.0 * grow, 6.0 * grow, 0.2 * (1 - np.exp(-t))]), ["m", "I", "c"]


def test_hook_detection() -> None:
    class Silent:
        pass

    class Logging:
        def log_names(self) -> tuple[str, ...]:
            return ("a", "b")

        def log_source(self) -> tuple[np.ndarray, np.ndarray]:
            return np.array([1.0, 2.0]), np.array([0, 1])

    class HalfHook:  # names without values: no log
        def log_names(self) -> tuple[str, ...]:
            return ("a",)

    assert law_log_names(Silent()) == ()
    assert law_log_names(HalfHook()) == ()
    assert law_log_names(None) == ()
    assert law_log_names(Logging()) == ("a", "b")


class _Source:
    """A law's log hook giving ``values`` and ``index``."""

    def __init__(self, values: object, index: object) -> None:
        self.values, self.index = values, index

    def log_source(self) -> tuple[object, object]:
        return self.values, self.index


def test_the_log_source_is_the_laws_own_array_and_an_index_within_it() -> None:
    values = np.arange(5.0)
    got, index = check_log_source(_Source(values, [4, 0]), 2)
    assert got is values  # not a copy: the record reads it at every sample
    assert index.dtype == np.int64 and index.tolist() == [4, 0]
    bad: list[tuple[object, object, str]] = [
        (values.astype(np.float32), [0, 1], "float64"),
        (values[::2], [0, 1], "C-contiguous"),
        (values.reshape(5, 1), [0, 1], "1-D"),
        (values.tolist(), [0, 1], "list"),
        (values, [0, 1, 2], r"index of 2 integers"),
        (values, [0.0, 1.0], r"index of 2 integers"),
        (values, [0, 5], r"0\.\.4"),
        (values, [-1, 0], r"0\.\.4"),
    ]
    for v, i, message in bad:
        with pytest.raises(ControlError, match=message) as err:
            check_log_source(_Source(v, i), 2)
        assert "_Source.log_source()" in str(err.value)
        assert err.value.key in ("log_source.values", "log_source.index")


def test_a_result_without_a_log_has_an_empty_one_and_no_names() -> None:
    r = _result()
    assert r.law_log.shape == (N, 0)
    assert "law_log_names" not in r.meta


def test_the_log_is_saved_loaded_and_truncated_with_its_names(tmp_path: Path) -> None:
    log, names = _estimates()
    r = _result(log, names)
    back = Result.load(r.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.law_log, log)
    assert back.meta["law_log_names"] == names
    assert not back.law_log.flags.writeable
    short = r.truncated(7)
    np.testing.assert_array_equal(short.law_log, log[:7])


def test_a_file_written_before_the_log_existed_loads_with_an_empty_one(tmp_path: Path) -> None:
    r = _result()
    path = tmp_path / "old.npz"
    np.savez(
        path,
        **{name: getattr(r, name) for name in ARRAY_NAMES},
        meta=np.array('{"name": "old", "status": "ok", "events": []}'),
    )
    assert Result.load(path).law_log.shape == (N, 0)


def test_a_log_that_does_not_match_its_names_is_refused(tmp_path: Path) -> None:
    log, names = _estimates()
    with pytest.raises(BadInputError, match="law_log"):
        _result(log, names[:2])
    with pytest.raises(BadInputError, match="law_log"):
        _result(log[:-1], names)
    with pytest.raises(BadInputError, match="law_log_names"):
        _result(log, [1, 2, 3])  # type: ignore[list-item]
    with pytest.raises(BadInputError, match="real numbers"):
        _result(np.full((N, 3), "x"), names)
    # a file whose meta lost the names
    path = _result(log, names).save(tmp_path / "r.npz")
    with np.load(path) as npz:
        arrays = {k: npz[k] for k in npz.files if k != "meta"}
    np.savez(path, **arrays, meta=np.array('{"name": "x", "status": "ok", "events": []}'))
    with pytest.raises(BadInputError, match="law_log"):
        Result.load(path)


def test_the_figure_is_drawn_only_when_the_law_logged_signals(tmp_path: Path) -> None:
    log, names = _estimates()
    written = plot_result(_result(log, names), tmp_path / "with")
    assert [p.stem for p in written] == [*FIGURE_NAMES, "law_log"]
    width, height = png_size(written[-1])
    assert width >= 400 and height >= 400
    written = plot_result(_result(), tmp_path / "without")
    assert [p.stem for p in written] == list(FIGURE_NAMES)
    # a run's output folder clears a stale law_log.png with the other figures
    assert tmp_path / "o" / "law_log.png" in RunOutput(tmp_path / "o").figures


def test_the_simulator_records_the_law_signals_at_every_sample() -> None:
    """The paper's law logs nothing; the adaptive one its estimates, one row per sample."""
    scenario = "scenarios/paper_contact.toml"
    plain = simulate(load_scenario(scenario, overrides={"sim.duration": 0.01}))
    assert plain.law_log.shape == (plain.n_samples, 0)
    assert "law_log_names" not in plain.meta
    adaptive = simulate(
        load_scenario(
            scenario,
            overrides={
                "sim.duration": 0.02,
                "control.law": "arimoto_adaptive",
                "sim.model_mass_factor": 0.9,
            },
        )
    )
    names = adaptive.meta["law_log_names"]
    assert adaptive.law_log.shape == (adaptive.n_samples, len(names)) and names
    # sample i holds the estimates the command of sample i used: θ̂(0), then updated ones
    np.testing.assert_array_equal(
        adaptive.law_log[0], adaptive.meta["controller"]["settings"]["theta0"]
    )
    assert np.any(adaptive.law_log[-1] != adaptive.law_log[0])
