"""experiments/device_check.py without compiling: monte_carlo and simulate are stubbed."""
import importlib.util
import json
import pathlib
from types import SimpleNamespace

import jax
import numpy as np
import pytest

from jaxdda.montecarlo import MonteCarlo

pytestmark = pytest.mark.smoke  # no compilation

PATH = pathlib.Path(__file__).resolve().parents[1] / "experiments" / "device_check.py"
spec = importlib.util.spec_from_file_location("device_check", PATH)
dc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(dc)


def fake_monte_carlo(scene, steps, *, velocity, **kwargs):
    b = len(velocity)
    converged = np.arange(b) % 4 != 0
    return MonteCarlo(observables={"runout": np.ones((b, 3))}, converged=converged,
                      iterations=np.arange(b) % 7, residual=np.zeros(b), max_penetration=np.zeros(b),
                      n_bodies=np.full(b, 3), steps=steps, seconds=0.0, devices=1)


def fake_simulate(scene, steps, **kwargs):
    return SimpleNamespace(info=SimpleNamespace(iterations=np.full(steps, 12)), step_converged=np.ones(steps, bool))


@pytest.fixture
def stubbed(monkeypatch):
    monkeypatch.setattr(dc.jaxdda, "monte_carlo", fake_monte_carlo)
    monkeypatch.setattr(dc.jaxdda, "simulate", fake_simulate)


def test_defaults_and_flags():
    args = dc.parse([])
    assert (args.batches, args.steps, args.pile, args.pile_steps, args.budget) == ([1024, 65536], 300, [10000],
                                                                                  100, 600.0)
    args = dc.parse(["--batches", "256", "64", "--steps", "50", "--pile", "200", "--pile-steps", "20",
                     "--budget", "30", "--batch-size", "128", "--out", "x.json"])
    assert (args.batches, args.steps, args.pile, args.pile_steps, args.budget, args.batch_size, args.out) == \
        ([256, 64], 50, [200], 20, 30.0, 128, "x.json")
    assert dc.plan(args) == [("rockfall", 64, 50), ("rockfall", 256, 50), ("pile", 200, 20)]
    assert dc.plan(dc.parse(["--batches", "--pile", "5"])) == [("pile", 5, 100)]
    for bad in (["--steps", "0"], ["--batches", "-1"], ["--batch-size", "0"]):
        with pytest.raises(SystemExit):
            dc.parse(bad)


def test_budget_skips_the_cases_estimated_past_it(monkeypatch):
    """A case costs 5 s plus 1 ms per unit of work; the budget is 60 s."""
    calls = []

    def case(name):
        def run(size, steps, *rest):
            calls.append((name, size, steps, *rest))
            run_s = 1e-3 * size * steps
            return {"case": name, "size": size, "steps": steps, "run s": run_s, "wall s": 5.0 + run_s}
        return run

    monkeypatch.setattr(dc, "run_rockfall", case("rockfall"))
    monkeypatch.setattr(dc, "run_pile", case("pile"))
    rows = dc.run_cases(dc.parse(["--batches", "64", "256", "1024", "--steps", "100", "--pile", "200",
                                  "--budget", "60", "--batch-size", "32"]))
    # 64: 11.4 s; 256, estimated 30.6 s, fits (42 s); 1024, estimated 107 s, does not; the pile
    # has nothing to estimate from and runs
    assert calls == [("rockfall", 64, 100, 32), ("rockfall", 256, 100, 32), ("pile", 200, 100)]
    assert rows[2] == {"case": "rockfall", "size": 1024, "steps": 100, "skipped": "estimated 107 s, 18 s left"}
    assert dc.estimate(rows, "rockfall", 256 * 100) == pytest.approx(30.6)
    assert dc.run_cases(dc.parse(["--batches", "8", "--pile", "--budget", "0"]))[0]["skipped"] == "budget spent"


def test_a_failing_case_is_listed_and_the_others_run(monkeypatch):
    def rockfall(size, steps, batch_size):
        if size > 100:
            raise MemoryError("out of device memory")
        return {"case": "rockfall", "size": size, "steps": steps, "run s": 1.0, "wall s": 2.0}

    monkeypatch.setattr(dc, "run_rockfall", rockfall)
    monkeypatch.setattr(dc, "run_pile", lambda size, steps: {"case": "pile", "size": size, "run s": 1.0, "wall s": 1.0})
    rows = dc.run_cases(dc.parse(["--batches", "10", "1000", "--pile", "5", "--budget", "1000"]))
    assert [r["size"] for r in rows] == [10, 1000, 5]
    assert rows[1]["error"] == "MemoryError: out of device memory" and "run s" not in rows[1]
    assert "run s" in rows[2]


def test_json_and_table(stubbed, tmp_path, capsys):
    out = tmp_path / "check.json"
    dc.main(["--batches", "8", "--steps", "5", "--pile", "3", "--pile-steps", "4", "--note", "a smoke",
             "--out", str(out)])
    printed = capsys.readouterr().out
    assert "a smoke" in printed and "scenario-steps/s" in printed and "body-steps/s" in printed
    data = json.loads(out.read_text())
    assert data["note"] == "a smoke" and data["jax"] == jax.__version__ and data["float64"] is True
    assert data["device"] == str(jax.devices()[0]) and data["backend"] == jax.default_backend()
    rock, pile = data["cases"]
    for row in (rock, pile):
        assert {"compile s", "run s", "wall s", "rate", "unit", "converged", "iterations mean",
                "iterations max", "devices"} <= set(row)
    assert (rock["case"], rock["size"], rock["unit"]) == ("rockfall", 8, "scenario-steps/s")
    assert rock["converged"] == 0.75 and rock["iterations max"] == 6
    assert rock["rate"] == pytest.approx(8 * 5 / rock["run s"])
    assert (pile["case"], pile["size"], pile["unit"], pile["converged"], pile["iterations mean"]) == \
        ("pile", 3, "body-steps/s", 1.0, 12.0)
    assert pile["rate"] == pytest.approx(3 * 4 / pile["run s"])  # the 3 walls are not counted


def test_compile_clock_counts_overlaps_once():
    clock = dc.CompileClock()
    clock.spans = [(0.0, 2.0), (1.0, 3.0), (5.0, 6.0), (5.5, 5.7)]
    assert clock.seconds == 4.0
    with dc.CompileClock() as clock:
        jax.jit(lambda x: x * 3 + 1)(np.arange(7.0)).block_until_ready()
    assert clock.seconds > 0
    n = len(clock.spans)
    jax.jit(lambda x: x * 5 - 2)(np.arange(7.0)).block_until_ready()  # after the block: not counted
    assert len(clock.spans) == n
