"""docs/GUARANTEES.md (signals): a signal that arrives while native code runs Python (a ``dr.while_loop`` body
that Dr.Jit traces, a plugin constructor inside ``mi.load_dict``) is raised there as
:class:`a5mi.platform.interrupts.Interrupted` and comes back wrapped in a ``RuntimeError``; the command layer still
ends with ``128 + signal`` and one line, never the internal-error status 70."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from a5mi.cli.app import Console, guarded
from a5mi.platform import interrupts
from a5mi.platform.errors import ExitStatus

#: A command body whose signal arrives inside a Dr.Jit loop body (symbolic: Dr.Jit calls it from C++) or
#: inside a Python BSDF's constructor (called by Mitsuba's loader), outside any deferred block.
WRAPPED = r"""
import os, signal, sys
import drjit as dr
import mitsuba as mi
from a5mi.platform import interrupts
from a5mi.cli.app import Console, guarded
mi.set_variant("llvm_ad_rgb")
interrupts.install(lambda s: None)
where, name = sys.argv[1], sys.argv[2]
sig = getattr(signal, name)

def body(i):
    os.kill(os.getpid(), sig)
    for _ in range(1000):  # the handler runs at the next bytecode
        pass
    return (i + 1,)

class Boom(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        body(0)

mi.register_bsdf("boom", Boom)

def run():
    if where == "loop":
        dr.while_loop((mi.UInt32(0),), lambda i: i < 3, body)
    else:
        mi.load_dict({"type": "boom"})
    return 0

sys.exit(guarded(Console("a5"), False, run))
"""


@pytest.mark.parametrize("where", ["loop", "load_dict"])
@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM"])
def test_a_signal_inside_native_code_is_still_the_signal(where: str, name: str) -> None:
    p = subprocess.run([sys.executable, "-c", WRAPPED, where, name], capture_output=True, text=True, timeout=300)
    sig = getattr(signal, name)
    assert (p.returncode, p.stderr.splitlines()) == (128 + sig, [f"a5: error: interrupted ({name})"]), p.stderr


def test_signal_behind_reads_the_chain_and_the_folded_traceback() -> None:
    """Dr.Jit chains the exception (``__cause__``); Mitsuba folds the traceback's last line into its message;
    an exception that carries neither (and no signal arrived in this process) stands for no signal."""
    try:
        raise RuntimeError("dr.while_loop(): encountered an exception (see above).") from interrupts.Interrupted(15)
    except RuntimeError as exc:
        assert interrupts.signal_behind(exc) == 15
    folded = RuntimeError('[parser.cpp:1718] failed to instantiate plugin "boom": Traceback (most recent call '
                          'last):\n  File "x.py", line 13, in __init__\nInterrupted: 1')
    assert interrupts.signal_behind(folded) == 1
    assert interrupts.signal_behind(RuntimeError("x\nKeyboardInterrupt")) == signal.SIGINT
    assert interrupts.signal_behind(RuntimeError("Interrupted by the user? no: a plain bug")) == 0


def test_a_plain_bug_is_still_an_internal_error(capsys: pytest.CaptureFixture[str]) -> None:
    def body() -> int:
        raise RuntimeError("a bug")

    assert guarded(Console("a5"), False, body) == ExitStatus.SOFTWARE
    assert "internal error: RuntimeError: a bug" in capsys.readouterr().err
