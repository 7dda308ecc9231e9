"""``a5mi animate --scheduler``: joined as ``a5 -scheduler`` is (docs/CLI.md): ``tls://`` with
``--tls-ca/--tls-cert/--tls-key`` (or the Dask configuration's credentials), a plain ``tcp://`` scheduler only
with ``--insecure-scheduler``; each refusal is one line, exit 2, before a frame is written. The renders on such
a cluster are tested in tests/runtime/test_slurm.py (SLURM-started workers, bit for bit the one-process frames)."""

from __future__ import annotations

import pytest

from a5mi import PROJECT_ROOT

SCENE = str(PROJECT_ROOT / "scenes" / "animation.txt")


@pytest.mark.parametrize(("more", "message"), [
    (["--scheduler", "tcp://127.0.0.1:1"], "a plain tcp:// scheduler lets anyone who reaches it run code on its "
     "workers"),
    (["--tls-ca", "ca.pem"], "--tls-ca needs --scheduler"),
    (["--scheduler", "tls://127.0.0.1:1", "--tls-ca", "ca.pem"], "--tls-ca needs --tls-cert and --tls-key as well"),
    (["--scheduler", "tls://127.0.0.1:1", "--tls-ca", "a", "--tls-cert", "b", "--tls-key", "c"],
     "TLS credential 'a' is not a file"),
])
def test_animate_refuses_an_unauthenticated_scheduler(tmp_path, capsys, monkeypatch, more, message) -> None:
    from a5mi.cli import run_a5mi

    monkeypatch.chdir(tmp_path)
    assert run_a5mi(["animate", SCENE, "-o", str(tmp_path / "frames"), "--frames", "0:1", *more]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "frames").exists()
