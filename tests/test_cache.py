"""The persistent cache of compiled programs (``jaxdda.cache``): a new process loads a
scene's programs instead of compiling them, also after the scene file's parameters were
edited; damaged or foreign entries are compiled again; ``JAXDDA_CACHE`` moves or turns it
off; ``jaxdda cache`` shows and clears it. Reuse is asserted by JAX's compile events and
the cache's entry count, never by wall-clock time."""
import json
import os
import pathlib
import subprocess
import sys

import pytest

import jaxdda
from jaxdda import cache, cli
from jaxdda.scene.io import save_scene

HERE = pathlib.Path(__file__).parent
STEPS = 20

# Runs ``jaxdda run FILE`` in a fresh process and prints the compile counts and the summary.
RUN = f"""
import contextlib, io, json, sys
sys.path.insert(0, {str(HERE)!r})
from compiles import counting
from jaxdda import cli
out = io.StringIO()
with counting() as c, contextlib.redirect_stdout(out):
    status = cli.main(["run", sys.argv[1], "--steps", "{STEPS}", "--quiet"])
summary = [line for line in out.getvalue().splitlines() if "wall time" not in line]
print(json.dumps(dict(status=status, compiles=c.compiles, requests=c.requests, hits=c.hits, summary=summary)))
"""


def disk_on_slab(friction=0.3, density=2000.0, force=(5.0, 0.0)):
    sb = jaxdda.SceneBuilder(dt=1e-3)
    sb.add_material("rock", friction=friction, restitution=0.2)
    sb.add_polygon(vertices=[(-2, -0.5), (2, -0.5), (2, 0), (-2, 0)], density=density, fixed=True, material="rock")
    disk = sb.add_disk(center=(0, 0.3), radius=0.3, density=density, velocity=(0.5, 0.0), material="rock")
    sb.add_load(disk, force=force)
    return sb.build()


def environment(setting):
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_COMPILATION_CACHE_DIR", "JAXDDA_CACHE")}
    env["JAXDDA_CACHE"] = str(setting)
    return env


def run(scene_file, setting):
    done = subprocess.run([sys.executable, "-c", RUN, str(scene_file)], env=environment(setting),
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1]), done.stderr


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "disk.toml"
    save_scene(disk_on_slab(), path, steps=STEPS)
    return path


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return tmp_path_factory.mktemp("xla")


@pytest.fixture(scope="module")
def first(scene_file, store):
    return run(scene_file, store)[0]


def test_a_fresh_cache_compiles_and_keeps_every_program(first, store):
    assert first["status"] == 0 and first["compiles"] > 0
    assert first["hits"] == 0 and first["requests"] == first["compiles"]
    assert cache.size(store)[0] >= first["compiles"]


def test_a_second_process_loads_every_program(scene_file, store, first):
    entries = cache.size(store)[0]
    second, _ = run(scene_file, store)
    assert second["requests"] == second["compiles"] == first["compiles"]
    assert second["hits"] == second["requests"]  # nothing compiled
    assert cache.size(store)[0] == entries  # nothing new written
    assert second["summary"] == first["summary"]


def test_a_scene_file_edited_in_its_parameters_reuses_the_programs(tmp_path, store, first):
    edited = tmp_path / "edited.toml"
    save_scene(disk_on_slab(friction=0.55, density=2600.0, force=(-3.0, 1.0)), edited, steps=STEPS)
    entries = cache.size(store)[0]
    again, _ = run(edited, store)
    assert again["hits"] == again["requests"] == first["compiles"]
    assert cache.size(store)[0] == entries
    assert again["summary"] != first["summary"]  # it did run the edited scene


@pytest.mark.smoke
def test_off_turns_the_cache_off(monkeypatch):
    for word in ("off", "0", "false", "No"):
        monkeypatch.setenv("JAXDDA_CACHE", word)
        assert cache.folder() is None
    probe = "import jax, jaxdda; print(jax.config.jax_enable_compilation_cache, jax.config.jax_compilation_cache_dir)"
    done = subprocess.run([sys.executable, "-c", probe], env=environment("off"), capture_output=True, text=True,
                          check=True)
    assert done.stdout.split() == ["False", "None"]


@pytest.mark.smoke
def test_the_folder_follows_the_environment(tmp_path, monkeypatch):
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    monkeypatch.delenv("JAXDDA_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.folder() == tmp_path / "xdg" / "jaxdda" / "xla"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.folder() == tmp_path / "home" / ".cache" / "jaxdda" / "xla"
    monkeypatch.setenv("JAXDDA_CACHE", str(tmp_path / "mine"))
    assert cache.folder() == tmp_path / "mine"
    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "jax"))  # the user's JAX setting wins
    assert cache.folder() == tmp_path / "jax"


@pytest.mark.smoke
def test_the_cache_command_shows_and_clears(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("JAX_COMPILATION_CACHE_DIR", raising=False)
    folder = tmp_path / "xla"
    (folder / "sub").mkdir(parents=True)
    (folder / "a").write_bytes(b"x" * 1000)
    (folder / "sub" / "b").write_bytes(b"y" * 2000)
    monkeypatch.setenv("JAXDDA_CACHE", str(folder))
    assert cli.main(["cache"]) == 0
    assert capsys.readouterr().out.strip() == f"{folder} holds 2 compiled programs, 0.0 MiB"
    assert cli.main(["cache", "--clear"]) == 0
    assert capsys.readouterr().out.strip() == f"{folder} deleted 2 compiled programs, 0.0 MiB"
    assert cache.size(folder) == (0, 0) and not folder.exists()
    monkeypatch.setenv("JAXDDA_CACHE", "off")
    assert cli.main(["cache"]) == 0
    assert "off" in capsys.readouterr().out


def test_damaged_and_foreign_entries_are_compiled_again(scene_file, store, first):
    """Last in the file: it damages the module's cache in place."""
    entries = [f for f in store.rglob("*") if f.is_file()]
    for f in entries:
        f.write_bytes(b"not an executable" + f.read_bytes()[:64][::-1])
    (store / "foreign-entry").write_bytes(os.urandom(256))
    out, stderr = run(scene_file, store)
    assert out["status"] == 0 and out["summary"] == first["summary"]
    assert out["hits"] == 0 and out["compiles"] == first["compiles"]  # each one compiled again
    assert "compilation cache" in stderr.lower()  # JAX said why
