"""Where the service looks for libraries, and what it says when one it should serve is not there."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.libraries import LibraryRegistry, required_animals
from synth_core.build import library_store
from synth_core.build.artifact import SUFFIX
from synth_core.build.library_store import library_dir


def test_library_dir_is_per_user_not_the_working_directory(monkeypatch: pytest.MonkeyPatch,
                                                           tmp_path: Path) -> None:
    monkeypatch.delenv("QUADSYNTH_LIBRARY_DIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("XDG_DATA_HOME", raising=False)
    monkeypatch.chdir(tmp_path)
    assert library_dir() == tmp_path / "home" / ".local" / "share" / "quadsynth" / "library"
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    assert library_dir() == tmp_path / "data" / "quadsynth" / "library"
    monkeypatch.setenv("QUADSYNTH_LIBRARY_DIR", str(tmp_path / "mine"))
    assert library_dir() == tmp_path / "mine"


def test_required_animals_default_to_the_built_in_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("QUADSYNTH_LIBRARIES", raising=False)
    assert required_animals() == ("horse", "dog")
    monkeypatch.setenv("QUADSYNTH_LIBRARIES", " horse, cat ,")
    assert required_animals() == ("horse", "cat")


def test_a_configured_animal_without_a_file_is_missing_and_the_registry_incomplete(tmp_path: Path) -> None:
    registry = LibraryRegistry(tmp_path, required=("horse", "cat"))
    registry.load()
    assert sorted(registry.libraries) == ["dog", "horse"] and not registry.complete
    states = {s.name: (s.state, s.reason) for s in registry.status()}
    assert states["horse"] == ("loaded", "") and states["dog"][0] == "loaded"
    assert states["cat"][0] == "missing" and "QUADSYNTH_LIBRARIES" in states["cat"][1]
    (tmp_path / f"cat{SUFFIX}").write_bytes((tmp_path / f"dog{SUFFIX}").read_bytes())  # a dog named cat
    again = LibraryRegistry(tmp_path, required=("horse", "dog"))
    again.load()
    assert not again.complete and again.errors == {f"dog{SUFFIX}": "a library named 'dog' is already loaded"}
    whole = LibraryRegistry(tmp_path, required=("horse",))
    (tmp_path / f"cat{SUFFIX}").unlink()
    whole.load()
    assert whole.complete and [s.state for s in whole.status()] == ["loaded", "loaded"]


def test_a_built_in_library_built_by_other_code_is_built_again_and_the_old_file_kept(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The library directory outlives a checkout: a built-in file whose stamp names other code
    (or that has none) is rebuilt, the old one moved aside; a current one is left alone."""
    monkeypatch.setattr(library_store, "BUILTIN_ANIMALS", ("dog",))
    first = library_store.ensure_builtin_libraries(tmp_path)
    assert [p.name for p in first] == ["dog.qslib.npz"]
    stamp = tmp_path / "dog.qslib.npz.source"
    assert stamp.read_text().strip() == library_store.builtin_source()
    assert library_store.ensure_builtin_libraries(tmp_path) == []  # current: not built again
    stamp.write_text("0123456789abcdef\n")  # built by an older version
    old = (tmp_path / "dog.qslib.npz").read_bytes()
    assert [p.name for p in library_store.ensure_builtin_libraries(tmp_path)] == ["dog.qslib.npz"]
    assert (tmp_path / "dog.qslib.npz.old").read_bytes() == old
    assert stamp.read_text().strip() == library_store.builtin_source()
    stamp.unlink()  # no stamp at all (a file from before stamps, or the user's own)
    assert len(library_store.ensure_builtin_libraries(tmp_path)) == 1 and stamp.exists()


def test_the_stamp_digests_every_module_that_builds_a_library() -> None:
    """A built-in library is rebuilt when the code that made it changes: every synth_core module a
    build (and the bank the service makes of it) imports must be in the digest, whatever the
    package layout (a module moved out of it would silently stop counting)."""
    import subprocess
    import sys

    code = ("import sys; from synth_core.build.animals import build_builtin; "
            "from synth_core.runtime.bank import build_bank; build_bank(build_builtin('dog')); "
            "print('\\n'.join(m.__file__ for n, m in sys.modules.items() if n.startswith('synth_core')))")
    loaded = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    used = {Path(f).resolve() for f in loaded.stdout.split()}
    digested = {f.resolve() for f in library_store.builtin_source_files()}
    assert len(used) > 10 and used <= digested, sorted(str(f) for f in used - digested)
