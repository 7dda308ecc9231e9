"""plugins/syntax.py: ``@dr.syntax`` with its transformed code kept on disk, authenticated (process start-up)."""

from __future__ import annotations

import types

import drjit as dr
import pytest

from a5mi.plugins import syntax as syntax_cache


def countdown(n, step=1):  # a Python while-loop over a Dr.Jit value: dr.syntax makes it a symbolic loop
    i = dr.zeros(type(n), dr.width(n))
    while n > 0:
        n -= step
        i += 1
    return i


def _folder(tmp_path, monkeypatch):
    monkeypatch.setenv("A5MI_CACHE_DIR", str(tmp_path))
    return tmp_path / "syntax"


def test_cached_function_is_the_transformed_one_and_is_read_back(tmp_path, monkeypatch, mi) -> None:
    folder = _folder(tmp_path, monkeypatch)
    reference = syntax_cache.TRANSFORM(countdown)
    first = syntax_cache.syntax(countdown)
    files = sorted(folder.iterdir())
    assert files == sorted([syntax_cache.cache_path(countdown), folder / syntax_cache.KEY_NAME])
    assert (folder / syntax_cache.KEY_NAME).stat().st_mode & 0o777 == 0o600
    assert first.__code__.co_code == reference.__code__.co_code and first.__defaults__ == (1,)

    def no_transform(*_args, **_kwargs):
        raise AssertionError("transformed again although cached")

    monkeypatch.setattr(syntax_cache, "TRANSFORM", no_transform)
    again = syntax_cache.syntax(countdown)
    assert isinstance(again, types.FunctionType) and again.__code__.co_code == reference.__code__.co_code
    assert again.__globals__ is countdown.__globals__
    n = mi.UInt32([0, 3, 5])
    assert list(again(n)) == list(reference(mi.UInt32([0, 3, 5]))) == [0, 3, 5]
    assert list(again(mi.Int32([4, 9]), 2)) == [2, 5]


def test_damaged_or_foreign_cache_files_are_transformed_again(tmp_path, monkeypatch, mi) -> None:
    import marshal

    _folder(tmp_path, monkeypatch)
    path = syntax_cache.cache_path(countdown)
    path.parent.mkdir(parents=True)
    foreign = marshal.dumps(test_damaged_or_foreign_cache_files_are_transformed_again.__code__)
    for content in (b"", b"\x00garbage", foreign):
        path.write_bytes(content)
        f = syntax_cache.syntax(countdown)
        assert f.__code__.co_name == "countdown" and list(f(mi.UInt32([2]))) == [2]
        assert marshal.loads(path.read_bytes()[syntax_cache.TAG_BYTES:]).co_name == "countdown"  # rewritten


def test_an_edited_function_gets_its_own_file(tmp_path, monkeypatch) -> None:
    _folder(tmp_path, monkeypatch)

    def edited(n, step=1):
        i = dr.zeros(type(n), dr.width(n))
        while n > 1:
            n -= step
            i += 1
        return i

    assert syntax_cache.cache_path(edited) != syntax_cache.cache_path(countdown)


def test_unwritable_cache_and_options_fall_back_to_dr_syntax(tmp_path, monkeypatch, mi, capsys) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("A5MI_CACHE_DIR", str(blocker))
    assert list(syntax_cache.syntax(countdown)(mi.UInt32([3]))) == [3]
    shown = syntax_cache.syntax(print_code=True)(countdown)
    assert "while_loop" in capsys.readouterr().out and list(shown(mi.UInt32([1]))) == [1]


def test_cached_drjit_syntax_replaces_and_restores_dr_syntax(tmp_path, monkeypatch) -> None:
    _folder(tmp_path, monkeypatch)
    original = dr.syntax
    with syntax_cache.cached_drjit_syntax():
        assert dr.syntax is syntax_cache.syntax
        dr.syntax(countdown)
    assert dr.syntax is original
    with pytest.raises(RuntimeError), syntax_cache.cached_drjit_syntax():
        raise RuntimeError("boom")
    assert dr.syntax is original
    assert syntax_cache.cache_path(countdown).is_file()


def _impostor_code():
    """A code object named ``countdown`` from this file that returns 42: what a planted entry would hold."""
    def countdown(n, step=1):
        return n * 0 + 42
    return countdown.__code__


def _no_transform(monkeypatch):
    calls = []
    real = syntax_cache.TRANSFORM

    def counting(f, **options):
        calls.append(f)
        return real(f, **options)

    monkeypatch.setattr(syntax_cache, "TRANSFORM", counting)
    return calls


def test_tampered_entries_are_not_executed(tmp_path, monkeypatch, mi) -> None:
    """An entry without a valid tag (planted unsigned, signed with another key, or edited after signing) is
    ignored: the function is transformed again and the entry rewritten with a valid tag."""
    import marshal

    folder = _folder(tmp_path, monkeypatch)
    syntax_cache.syntax(countdown)                      # creates the folder, the key and a valid entry
    path = syntax_cache.cache_path(countdown)
    impostor = marshal.dumps(_impostor_code())
    signed = path.read_bytes()
    for planted in (impostor,                                                 # no tag at all
                    bytes(syntax_cache.TAG_BYTES) + impostor,                 # a wrong tag
                    signed[:syntax_cache.TAG_BYTES] + impostor,               # a real tag, another payload
                    signed[:-1] + bytes([signed[-1] ^ 1])):                   # one bit of the entry flipped
        path.write_bytes(planted)
        calls = _no_transform(monkeypatch)
        f = syntax_cache.syntax(countdown)
        assert calls == [countdown] and list(f(mi.UInt32([3]))) == [3]    # the real function, transformed again
        assert path.read_bytes() == signed                                 # and rewritten, signed
    assert (folder / syntax_cache.KEY_NAME).stat().st_size == syntax_cache.TAG_BYTES


def test_a_folder_or_key_others_can_touch_disables_the_cache(tmp_path, monkeypatch, mi) -> None:
    """A group/world-writable cache folder, or a key file others can read, means no cache: nothing is read
    (a planted entry never runs) and nothing is written."""
    import marshal

    folder = _folder(tmp_path, monkeypatch)
    syntax_cache.syntax(countdown)
    path = syntax_cache.cache_path(countdown)
    key = folder / syntax_cache.KEY_NAME
    for target, mode, restore in ((folder, 0o777, 0o700), (tmp_path, 0o775, 0o700), (key, 0o644, 0o600)):
        target.chmod(mode)
        planted = marshal.dumps(_impostor_code())
        path.write_bytes(planted)
        calls = _no_transform(monkeypatch)
        f = syntax_cache.syntax(countdown)
        assert calls == [countdown] and list(f(mi.UInt32([2]))) == [2]
        assert path.read_bytes() == planted                                # untouched: not rewritten either
        target.chmod(restore)
        path.unlink()
