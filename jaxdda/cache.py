"""The persistent cache of compiled programs: XLA's executables kept on disk, so that a
new process (a second ``jaxdda run``, a restarted notebook kernel) loads a scene's step
instead of compiling it again.

On by default, in ``$XDG_CACHE_HOME/jaxdda/xla`` (``~/.cache/jaxdda/xla``). The environment
variable ``JAXDDA_CACHE`` moves it (a folder) or turns it off (``off``, ``0``, ``false``,
``no``); a folder the user gave JAX itself (``JAX_COMPILATION_CACHE_DIR``) wins over a
folder given here.
Entries are keyed by the program, the jax version and the compile options, so one written
by another version is simply not found; one that fails to load is compiled again (JAX
warns). Parameters (friction, density, loads) are arrays, not constants of the program,
so a scene file edited in a value reuses its program."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import jax

OFF = ("off", "0", "false", "no", "none")


def folder() -> Path | None:
    """The cache folder this process uses, or None where caching is off."""
    setting = os.environ.get("JAXDDA_CACHE", "").strip()
    if setting.lower() in OFF and setting:
        return None
    given = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if given:
        return Path(given).expanduser()
    if setting:
        return Path(setting).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "jaxdda" / "xla"


def enable() -> None:
    """Point JAX's compilation cache at ``folder()`` (called when jaxdda is imported).
    Every program is kept, however fast it compiled: a step's pieces are many and small."""
    path = folder()
    if path is None:
        jax.config.update("jax_enable_compilation_cache", False)
        return
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def size(path: Path) -> tuple[int, int]:
    """(entries, bytes) in the cache folder ``path``."""
    files = [f for f in path.rglob("*") if f.is_file()] if path.is_dir() else []
    return len(files), sum(f.stat().st_size for f in files)


def clear(path: Path) -> tuple[int, int]:
    """Delete the cache folder ``path``; returns what it held (entries, bytes)."""
    held = size(path)
    if path.is_dir():
        shutil.rmtree(path)
    return held
