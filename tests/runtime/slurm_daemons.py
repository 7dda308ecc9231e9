"""A real single-node SLURM for the tests and the benchmark: ``munged``, ``slurmctld`` and ``slurmd`` (Debian's
``munge``, ``slurmctld``, ``slurmd`` and ``slurm-client`` packages, installed by ``make setup``) started as root
from a generated ``slurm.conf`` in a temporary folder, and stopped afterwards.

The configuration (docs/GRADING.md "On a SLURM cluster"): one node ``localhost`` (``NodeAddr=127.0.0.1``, two
CPUs, ``RealMemory`` = 80% of this machine's), one partition ``a5mi`` (the default), ``auth/munge`` through a
munge socket and key of the temporary folder, no cgroups (``ProctrackType=proctrack/linuxproc``,
``TaskPlugin=task/none``: containers rarely delegate cgroups), no accounting database, ``KillWait=2`` (SIGTERM to
SIGKILL at a time limit), ports chosen free on 127.0.0.1, and ``CommunicationParameters=NoInAddrAny,
NoCtldInAddrAny``: every daemon listens on 127.0.0.1 only. :func:`slurm_problem` says why it cannot run here
(not root, a program missing); :class:`LocalSlurm` is a context manager that starts and stops it, killing only
the processes it started (and every job process under its ``slurmd``).
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

PROGRAMS = ("munged", "slurmctld", "slurmd", "sbatch", "squeue", "scancel", "scontrol", "sinfo")
PACKAGES = "munge slurmctld slurmd slurm-client"


def slurm_problem() -> str:
    """Why the local SLURM cannot start here ('' when it can): not root, or a program missing."""
    if os.geteuid() != 0:
        return "not root: the SLURM daemons (munged, slurmctld, slurmd) are started as root"
    missing = [p for p in PROGRAMS if shutil.which(p) is None]
    if missing:
        return f"{', '.join(missing)} not installed (apt-get install {PACKAGES}; make setup does as root)"
    return ""


def installable() -> bool:
    """Whether ``make setup`` would have installed the daemons here (root and apt-get)."""
    return os.geteuid() == 0 and shutil.which("apt-get") is not None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _mem_mb() -> int:
    with open("/proc/meminfo") as f:
        kb = next(int(line.split()[1]) for line in f if line.startswith("MemTotal:"))
    return int(kb / 1024 * 0.8)


CONF = """ClusterName=a5mi
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort={ctld_port}
SlurmdPort={slurmd_port}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={root}/munge/munge.socket
CommunicationParameters=NoInAddrAny,NoCtldInAddrAny
MailProg=/bin/true
StateSaveLocation={root}/state
SlurmdSpoolDir={root}/spool
SlurmctldPidFile={root}/slurmctld.pid
SlurmdPidFile={root}/slurmd.pid
SlurmctldLogFile={root}/log/slurmctld.log
SlurmdLogFile={root}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
KillWait=2
InactiveLimit=0
MinJobAge=600
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 RealMemory={mem} State=UNKNOWN
PartitionName=a5mi Nodes=localhost Default=YES MaxTime=INFINITE State=UP
"""


class LocalSlurm:
    """``with LocalSlurm() as slurm:`` a running single-node SLURM (module docstring); ``slurm.env`` is the
    environment its clients need (``SLURM_CONF``), also set in ``os.environ`` while it runs."""

    def __init__(self, root: str | os.PathLike[str] | None = None) -> None:
        self._own_root = root is None
        self.root = Path(root or tempfile.mkdtemp(prefix="a5mi-slurm-"))
        self.procs: list[subprocess.Popen] = []
        self._old_conf: str | None = None

    @property
    def conf(self) -> Path:
        return self.root / "slurm.conf"

    @property
    def env(self) -> dict[str, str]:
        return {**os.environ, "SLURM_CONF": str(self.conf)}

    def _spawn(self, *argv: str, log: str) -> subprocess.Popen:
        out = open(self.root / "log" / log, "ab")  # noqa: SIM115 - the daemon's own stdout, closed at exit
        p = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, env=self.env, start_new_session=True)
        out.close()
        self.procs.append(p)
        return p

    def start(self) -> LocalSlurm:
        for d in ("state", "spool", "log", "munge"):
            (self.root / d).mkdir(parents=True, exist_ok=True)
        self.root.chmod(0o755)
        munge = self.root / "munge"
        munge.chmod(0o711)
        key = munge / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o400)
        self.conf.write_text(CONF.format(root=self.root, ctld_port=_free_port(), slurmd_port=_free_port(),
                                         mem=_mem_mb()))
        self._old_conf = os.environ.get("SLURM_CONF")
        os.environ["SLURM_CONF"] = str(self.conf)
        self._spawn("munged", "-F", "-f", "-S", str(munge / "munge.socket"), f"--key-file={key}",
                    f"--log-file={self.root / 'log' / 'munged.log'}", f"--pid-file={munge / 'munged.pid'}",
                    f"--seed-file={munge / 'munged.seed'}", log="munged.out")
        self._wait(lambda: (munge / "munge.socket").exists(), "munged")
        self._spawn("slurmctld", "-D", "-i", "-f", str(self.conf), log="slurmctld.out")
        self._wait(lambda: self._ok("sinfo", "-h"), "slurmctld")
        self._spawn("slurmd", "-D", "-N", "localhost", "-f", str(self.conf), log="slurmd.out")
        self._wait(lambda: self._ok("sinfo", "-h", "-o", "%t", check="idle"), "slurmd (node idle)")
        return self

    def _ok(self, *argv: str, check: str | None = None) -> bool:
        r = subprocess.run(argv, env=self.env, capture_output=True, text=True, timeout=30)
        return r.returncode == 0 and (check is None or r.stdout.strip() == check)

    def _wait(self, ready, what: str, seconds: float = 60.0) -> None:
        t = time.monotonic()
        while not ready():
            dead = [p.args[0] for p in self.procs if p.poll() is not None]
            if dead or time.monotonic() - t > seconds:
                raise RuntimeError(f"local SLURM: {what} did not start ({', '.join(dead) or 'timed out'}); logs in "
                                   f"{self.root / 'log'}:\n{self.log_tail()}")
            time.sleep(0.2)

    def log_tail(self, n: int = 15) -> str:
        out = []
        for f in sorted((self.root / "log").glob("*")):
            lines = f.read_text(errors="replace").splitlines()[-n:]
            out.append(f"== {f.name}\n" + "\n".join(lines))
        return "\n".join(out)

    def run(self, *argv: str) -> str:
        """A SLURM client command (``squeue``, ``scancel``, ``scontrol``) against this cluster: its stdout."""
        return subprocess.run(argv, env=self.env, capture_output=True, text=True, timeout=60, check=True).stdout

    def jobs(self, name: str | None = None) -> list[str]:
        """The ids of the jobs in the queue (pending, running, completing), of ``name`` if given."""
        argv = ["squeue", "-h", "-o", "%i"] + ([f"--name={name}"] if name else [])
        return self.run(*argv).split()

    def job_state(self, job: str) -> str:
        """``JobState`` of ``job`` (``scontrol show job``; ended jobs are kept ``MinJobAge`` seconds)."""
        for word in self.run("scontrol", "show", "job", job).split():
            if word.startswith("JobState="):
                return word.split("=", 1)[1]
        return ""

    def descendants(self) -> list[int]:
        """The pids of the processes this SLURM runs besides its daemons: ``slurmstepd`` (which detaches from
        ``slurmd``), the job scripts, the Dask workers and the sandboxes under them. They are found by the
        environment every one of them inherits: ``SLURM_CONF`` naming this cluster's ``slurm.conf``."""
        mark = f"SLURM_CONF={self.conf}".encode()
        daemons = {p.pid for p in self.procs}
        out = []
        for d in os.listdir("/proc"):
            if d.isdigit() and int(d) not in daemons and int(d) != os.getpid():
                try:
                    with open(f"/proc/{d}/environ", "rb") as f:
                        if mark in f.read().split(b"\0"):
                            out.append(int(d))
                except OSError:
                    continue
        return out

    def stop(self) -> None:
        jobs = self.descendants()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for p in reversed(self.procs):
                if p.poll() is None:
                    p.send_signal(sig)
            for p in reversed(self.procs):
                try:
                    p.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    pass
        for pid in jobs:  # a job process slurmd left (slurmstepd ends its jobs when told; be sure)
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self._old_conf is None:
            os.environ.pop("SLURM_CONF", None)
        else:
            os.environ["SLURM_CONF"] = self._old_conf
        if self._own_root:
            shutil.rmtree(self.root, ignore_errors=True)

    def __enter__(self) -> LocalSlurm:
        try:
            return self.start()
        except BaseException:
            self.stop()
            raise

    def __exit__(self, *exc: object) -> None:
        self.stop()
