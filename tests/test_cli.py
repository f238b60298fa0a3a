"""The jaxdda command, run in-process: examples, scene files, outputs and errors."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxdda.cli import main

ROOT = Path(__file__).resolve().parents[1]

MIXED = {
    "name": "mixed", "settings": {"dt": 0.001, "steps": 3},
    "materials": {"rock": {"friction": 0.5, "restitution": 0.2}},
    "bodies": [
        {"type": "polygon", "vertices": [[-10, -1], [10, -1], [10, 0], [-10, 0]], "density": 2000,
         "fixed": True, "material": "rock"},
        {"type": "disk", "center": [-4, 1.0], "radius": 1.0, "density": 1000, "material": "rock"},
        {"type": "ring", "center": [0, 2], "inner_radius": 0.5, "outer_radius": 1.5, "density": 1500,
         "velocity": [0.5, 0.0]},
        {"type": "polygon", "vertices": [[3, 0.5], [5, 0.5], [4, 2]], "density": 2500, "angular_velocity": 1.0},
    ],
}


def test_run_example_writes_npz_and_png(tmp_path, capsys):
    out, png = tmp_path / "x.npz", tmp_path / "x.png"
    vtk = tmp_path / "vtk"
    assert main(["run", "paper-7.1", "--steps", "5", "--out", str(out), "--plot", str(png), "--vtk", str(vtk),
                 "--vtk-every", "2", "--csv", str(tmp_path / "csv")]) == 0
    text = capsys.readouterr().out
    assert "paper-7.1" in text and "5 steps" in text and "converged" in text
    assert "wrote nothing: the scene has no measured or load points" in text
    assert not any((tmp_path / "csv").iterdir())
    assert data_shapes_of_points(out) == ((6, 0, 2), (6, 0, 2))
    assert png.stat().st_size > 1000
    assert sorted(p.name for p in vtk.glob("*_bodies_*.vtp")) == [f"paper-7.1_bodies_{k:06d}.vtp" for k in (0, 2, 4, 5)]
    assert (vtk / "paper-7.1_bodies.pvd").exists() and (vtk / "paper-7.1_contacts.pvd").exists()
    data = np.load(out)
    n, steps = 4, 5
    assert data["time"].shape == (steps + 1,)
    np.testing.assert_allclose(data["time"][-1], 5 * 0.001)
    assert data["centroid"].shape == (steps + 1, n, 2)
    assert data["rotation"].shape == (steps + 1, n)
    assert data["velocity"].shape == (steps + 1, n, 3)
    for key in ("iterations", "residual", "converged", "n_contacts"):
        assert data[key].shape == (steps,), key
    c = data["contact_valid"].shape[1]
    assert data["contact_valid"].shape == data["contact_a"].shape == data["contact_b"].shape == (steps, c)
    assert data["contact_force"].shape == data["contact_point"].shape == (steps, c, 2)
    assert data["converged"].dtype == bool and data["converged"].all()
    assert (data["contact_valid"].sum(1) == data["n_contacts"]).all()


def data_shapes_of_points(npz):
    data = np.load(npz)
    return data["measured_points"].shape, data["load_forces"].shape


def test_save_every_keeps_every_kth_step_of_the_same_run(tmp_path, capsys):
    full, sparse = tmp_path / "full.npz", tmp_path / "sparse.npz"
    assert main(["run", "paper-7.1", "--steps", "5", "--out", str(full), "--quiet"]) == 0
    assert main(["run", "paper-7.1", "--steps", "5", "--out", str(sparse), "--save-every", "2", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "(of the saved steps)" in text and "converged         every step" in text
    a, b = np.load(full), np.load(sparse)
    kept = [0, 2, 4, 5]  # every 2nd step and the last
    np.testing.assert_array_equal(b["time"], a["time"][kept])
    np.testing.assert_array_equal(b["centroid"], a["centroid"][kept])
    np.testing.assert_array_equal(b["iterations"], a["iterations"][[1, 3, 4]])  # steps 2, 4, 5


def test_run_scene_file(tmp_path, capsys):
    scene = tmp_path / "mixed.json"
    scene.write_text(json.dumps(MIXED))
    out, png = tmp_path / "m.npz", tmp_path / "m.png"
    assert main(["run", str(scene), "--out", str(out), "--plot", str(png)]) == 0  # steps from the file
    assert "mixed: 4 bodies, 3 steps" in capsys.readouterr().out
    data = np.load(out)
    assert data["centroid"].shape == (4, 4, 2)
    assert png.exists()


HANGING = {
    "name": "hanging", "settings": {"dt": 0.01, "steps": 12, "gravity": [0, -9.81]},
    "bodies": [
        {"type": "polygon", "vertices": [[-0.5, 1], [0.5, 1], [0.5, 2], [-0.5, 2]], "density": 1, "fixed": True},
        {"type": "disk", "center": [0, 0], "radius": 0.1, "density": 1000},
    ],
    "connectors": [{"type": "spring", "body_a": 0, "body_b": 1, "at_a": [0, 1], "at_b": [0, 0], "stiffness": 4000}],
}


def test_run_scene_file_with_a_connector_writes_an_animation(tmp_path, capsys):
    from PIL import Image

    scene = tmp_path / "hanging.json"
    scene.write_text(json.dumps(HANGING))
    gif = tmp_path / "h.gif"
    assert main(["run", str(scene), "--animate", str(gif), "--frames", "5"]) == 0
    assert "wrote" in capsys.readouterr().out
    with Image.open(gif) as image:
        assert image.n_frames == 5
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**HANGING, "connectors": [{**HANGING["connectors"][0], "stifness": 1}]}))
    assert "connectors[0].stifness: unknown key (did you mean 'stiffness'?" in fails(["run", str(bad)], capsys)


def fails(argv, capsys) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return captured.err


@pytest.mark.smoke
def test_errors_exit_2_with_a_message(tmp_path, capsys):
    assert "jaxdda: error: unknown example 'paper-9.9'" in fails(["run", "paper-9.9"], capsys)
    assert "no such scene file" in fails(["run", str(tmp_path / "absent.json")], capsys)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**MIXED, "bodies": [{"type": "disk", "center": [0, 0], "radius": 1}]}))
    assert "bodies[0].density: missing" in fails(["run", str(bad)], capsys)
    bad.write_text("{")
    assert "invalid JSON at line 1" in fails(["run", str(bad)], capsys)
    no_steps = tmp_path / "no_steps.json"
    no_steps.write_text(json.dumps({**MIXED, "settings": {"dt": 0.001}}))
    assert "--steps" in fails(["run", str(no_steps)], capsys)
    assert "does not exist" in fails(["run", "paper-7.1", "--out", str(tmp_path / "nodir" / "x.npz")], capsys)
    assert "positive integer" in fails(["run", "paper-7.1", "--steps", "0"], capsys)
    fails([], capsys)


@pytest.mark.smoke
def test_list(capsys):
    assert main(["list"]) == 0
    text = capsys.readouterr().out
    assert "paper-7.1" in text and "paper-7.5" in text and "pendulum" in text


@pytest.mark.smoke
def test_python_dash_m():
    result = subprocess.run([sys.executable, "-m", "jaxdda", "run", "no-such-example"], cwd=ROOT,
                            capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert result.returncode == 2
    assert result.stderr.startswith("jaxdda: error: unknown example")


@pytest.mark.smoke
def test_a_closed_pipe_stops_the_listing_quietly():
    """``jaxdda list | head -3``: the reader is gone before the listing is written."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        result = subprocess.run([sys.executable, "-m", "jaxdda", "list"], cwd=ROOT, stdout=write_end,
                                stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    finally:
        os.close(write_end)
    assert result.returncode == 1
    assert result.stderr == ""


@pytest.mark.smoke
def test_export_an_example(tmp_path, capsys):
    toml = tmp_path / "pull.toml"
    assert main(["export", "paper-7.8", str(toml)]) == 0
    assert "[[loads]]" in toml.read_text()
    assert "unknown example 'paper-9.9'" in fails(["export", "paper-9.9", str(toml)], capsys)


def test_export_an_example_and_run_the_file(tmp_path, capsys):
    toml = tmp_path / "pull.toml"
    assert main(["export", "paper-7.8", str(toml)]) == 0
    assert main(["run", str(toml), "--steps", "2", "--csv", str(tmp_path / "csv"), "--report", str(tmp_path / "pics"),
                 "--quiet"]) == 0
    assert "paper-7.8: 2 bodies, 2 steps" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "pics").iterdir()) == ["energy.png", "forces.png", "network.png",
                                                                   "paths.png"]
    table = np.genfromtxt(tmp_path / "csv" / "paper-7.8_loads.csv", delimiter=",", names=True)
    np.testing.assert_array_equal(table["load0_fx"], [1000.0] * 3)  # the example's pull


@pytest.mark.smoke
def test_ntdda_files_convert_to_a_scene_file(tmp_path, capsys):
    from jaxdda.scene.loader import load_scene

    data = ROOT / "tests" / "data" / "ntdda"
    out = tmp_path / "square.toml"
    assert main(["ntdda", str(data / "square.geo"), str(data / "square.ana"), "--out", str(out)]) == 0
    assert "2 blocks" in capsys.readouterr().out
    scene, steps = load_scene(out)
    assert scene.n_bodies == 2 and steps == 100
    assert "no such file" in fails(["ntdda", str(data / "absent.geo"), "--out", str(out)], capsys).lower()
