"""Dask workers as SLURM jobs (``a5mi grade --slurm``, docs/GRADING.md "On a SLURM cluster").

:func:`start_slurm_client` starts a ``dask_jobqueue.SLURMCluster`` in this process: its scheduler listens on
``tls://HOST:PORT`` and every worker is one ``sbatch`` job (one CPU, one single-threaded worker process under a
nanny) that connects back to it. The traffic is authenticated as on the local cluster
(:func:`a5mi.runtime.cluster.per_run_security`: a fresh self-signed key and certificate per run, the CA of every role,
mutual TLS required): the jobs need them as files, so the worker's key and certificate are written, mode 0600,
into a private folder (mode 0700) of the shared ``folder`` and removed when the cluster closes. No HTTP route is
served (dashboard, ``/info`` pages), by the scheduler or by a worker (``--no-dashboard``; the job script
exports ``DASK_DISTRIBUTED__WORKER__HTTP__ROUTES=[]``).

Jobs die: ``scancel``, a node lost, the wall-clock limit reached. The scheduler gives a dead worker's tasks to
another worker (:func:`a5mi.runtime.cluster.run_units`' guarantee), and the cluster keeps ``jobs`` jobs alive
(``adapt(minimum_jobs=jobs, maximum_jobs=jobs)``: a job that ended is submitted again). A client that is killed
leaves its jobs behind: a running worker exits when it loses its scheduler, but a job still pending starts later
and waits ``death_timeout`` seconds for a scheduler that is gone, holding its CPU. The jobs are named after the
folder (:func:`job_name`), and a client started again on the same folder cancels them first
(:func:`cancel_stale`).

Where the workers listen: ``host`` (default ``127.0.0.1``, the single-node configuration the tests run) is the
scheduler's address and each worker's; on a site whose jobs run on other nodes give ``interface`` (the
nodes' network interface, e.g. ``ib0``) instead, which both the scheduler and the workers bind to.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from a5mi.platform.errors import UsageError
from a5mi.runtime.cluster import per_run_security
from a5mi.runtime.extras import require

#: The name of every job (``squeue --name``) when no folder names it (:func:`job_name`).
JOB_NAME = "a5mi-worker"


def job_name(folder: str | os.PathLike[str]) -> str:
    """The jobs' name for ``folder``: ``a5mi-`` and the first 8 hex digits of the SHA-256 of its real path, so
    that a client restarted on the same folder finds the jobs its killed predecessor left."""
    digest = hashlib.sha256(os.path.realpath(folder).encode()).hexdigest()[:8]
    return f"a5mi-{digest}"


def cancel_stale(name: str) -> None:
    """``scancel --name NAME --user ME``: end the jobs a killed client of the same folder left (a pending one
    would start and wait ``death_timeout`` seconds for a scheduler that is gone, holding its CPU)."""
    subprocess.run(["scancel", f"--name={name}", f"--user={pwd.getpwuid(os.getuid()).pw_name}"],
                   capture_output=True, timeout=60, check=False)


@dataclass(frozen=True)
class SlurmOptions:
    """What each job asks SLURM for (``a5mi grade --slurm`` flags): ``jobs`` jobs of one CPU and ``memory``
    (``--mem``; also the worker's Dask memory limit) for ``walltime`` (``--time``, ``[D-]HH:MM:SS``), in
    ``partition`` (``--partition``, else the site's default) charged to ``account`` (``--account``);
    ``directives``: more ``#SBATCH`` options, each as ``sbatch`` takes it (``--qos=short``)."""

    jobs: int = 2
    partition: str | None = None
    account: str | None = None
    walltime: str = "01:00:00"
    memory: str = "4GB"
    host: str = "127.0.0.1"
    interface: str | None = None
    directives: tuple[str, ...] = ()
    death_timeout: float = 60.0


def _cluster_kwargs(opts: SlurmOptions, folder: Path, tls_dir: Path, security: Any,
                    name: str = JOB_NAME) -> dict[str, Any]:
    """The ``SLURMCluster`` arguments of ``opts`` (module docstring)."""
    where = ["--interface", opts.interface] if opts.interface else ["--host", opts.host]
    # Dask's HTTP servers (no routes: every request 404) listen on loopback only
    scheduler: dict[str, Any] = {"dashboard_address": "127.0.0.1:0", "dashboard": False}
    scheduler.update({"interface": opts.interface} if opts.interface else {"host": opts.host})
    return dict(
        cores=1, processes=1, memory=opts.memory, walltime=opts.walltime, queue=opts.partition,
        account=opts.account, job_name=name, python=sys.executable, protocol="tls://", security=security,
        scheduler_options=scheduler, worker_extra_args=[*where, "--no-dashboard", "--dashboard-address",
                                                        "127.0.0.1:0"],
        job_extra_directives=list(opts.directives), log_directory=str(folder / "logs"),
        shared_temp_directory=str(tls_dir), local_directory="${TMPDIR:-/tmp}", death_timeout=opts.death_timeout,
        job_script_prologue=["export DASK_DISTRIBUTED__WORKER__HTTP__ROUTES='[]'",
                             "export DASK_DISTRIBUTED__WORKER__DAEMON=False"])


def _private_folder(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    path.chmod(0o700)
    return path


@contextlib.contextmanager
def start_slurm_client(opts: SlurmOptions, folder: str | os.PathLike[str], *, security: Any = None) -> Iterator[Any]:
    """A ``distributed.Client`` of a ``SLURMCluster`` of ``opts.jobs`` worker jobs (module docstring); the
    jobs' logs go to ``folder/logs``, the run's worker credentials to ``folder/tls`` (removed on exit).
    ``security``: a ``distributed.security.Security`` of PEM files on the shared file system (one CA; the
    scheduler's, the workers' and the client's certificate and key), for a cluster that other clients join
    (``a5 -scheduler``, ``a5mi animate --scheduler`` with the same files); default: the run's own
    (:func:`a5mi.runtime.cluster.per_run_security`).
    ``folder`` must be on a file system the nodes share. The job script is checked first
    (:func:`check_submission`: an unknown partition is a :class:`~a5mi.platform.errors.UsageError`); the jobs are
    submitted in the background, so the client may hold no worker yet (SLURM starts them when it can:
    ``client.wait_for_workers``). On exit the jobs are cancelled (``scancel``)."""
    dask, distributed = require("dask", "slurm"), require("distributed", "slurm")
    dask_jobqueue = require("dask_jobqueue", "slurm")
    if shutil.which("sbatch") is None:
        raise UsageError("--slurm: no 'sbatch' on PATH (run a5mi grade --slurm on a SLURM submit node)")
    folder = Path(folder)
    tls_dir = _private_folder(folder / "tls")
    name = job_name(folder)
    cancel_stale(name)
    if security is None:
        security = per_run_security()
    settings = {"distributed.scheduler.http.routes": [], "distributed.worker.http.routes": [],
                "distributed.scheduler.allowed-failures": 5, "distributed.logging.distributed": "error"}
    cluster = None
    try:
        with dask.config.set(settings):
            cluster = dask_jobqueue.SLURMCluster(**_cluster_kwargs(opts, folder, tls_dir, security, name))
            check_submission(cluster.job_script())
            cluster.adapt(minimum_jobs=opts.jobs, maximum_jobs=opts.jobs)
            client = distributed.Client(cluster, security=security)
            try:
                yield client
            finally:
                client.close()
    finally:
        if cluster is not None:
            cluster.close()
            for attr, value in list(vars(cluster).items()):  # the worker credentials dask-jobqueue wrote
                if attr.startswith("_job_") and hasattr(value, "close"):
                    value.close()
        shutil.rmtree(tls_dir, ignore_errors=True)


def check_submission(script: str) -> None:
    """``sbatch --test-only`` of the job ``script``: SLURM checks the partition, account, time limit, memory
    and every other directive without queueing anything; a refusal is a :class:`~a5mi.platform.errors.UsageError` with
    ``sbatch``'s first error line."""
    with tempfile.NamedTemporaryFile("w", suffix=".sh", prefix="a5mi-job-") as f:
        f.write(script)
        f.flush()
        r = subprocess.run(["sbatch", "--test-only", f.name], capture_output=True, text=True, timeout=60,
                           check=False)
    if r.returncode != 0:
        lines = [ln.strip() for ln in r.stderr.splitlines() if "error" in ln.lower()] or r.stderr.splitlines()
        why = (lines or [f"status {r.returncode}"])[0].removeprefix("sbatch: error: ")
        raise UsageError(f"--slurm: sbatch refuses the worker job: {why[:300]}")


__all__ = ["JOB_NAME", "SlurmOptions", "cancel_stale", "check_submission", "job_name", "start_slurm_client"]
