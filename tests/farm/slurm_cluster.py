"""A one-node Slurm cluster on localhost, for the farm test: munged,
slurmctld and slurmd started from a generated configuration under one
temporary folder, and stopped again by their pid files.

Everything lives in that folder: the munge key (generated there, never
/etc/munge), munge's socket, slurm.conf, the controller's state, slurmd's
spool, the pid files and the logs. The ports are free ones picked at start,
so the cluster never meets a system Slurm or another test run. The node is
this machine under its real short hostname and CPU count, as slurmd checks
both. Root is needed (slurmd runs jobs as their user); CI runs as root.
"""

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

MUNGED, SLURMCTLD, SLURMD = "/usr/sbin/munged", "/usr/sbin/slurmctld", "/usr/sbin/slurmd"


class ClusterError(RuntimeError):
    pass


def free_ports(count):
    sockets = [socket.socket() for _ in range(count)]
    try:
        for s in sockets:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def slurm_conf(root, host, cpus, ctld_port, slurmd_port, munge_socket):
    return f"""\
ClusterName=coherent{ctld_port}
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={ctld_port}
SlurmdPort={slurmd_port}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={munge_socket}
StateSaveLocation={root}/state
SlurmdSpoolDir={root}/spool
SlurmctldPidFile={root}/slurmctld.pid
SlurmdPidFile={root}/slurmd.pid
SlurmctldLogFile={root}/slurmctld.log
SlurmdLogFile={root}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SchedulerParameters=kill_invalid_depend
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MailProg=/bin/true
NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=farm Nodes={host} Default=YES MaxTime=INFINITE State=UP
"""


def read_log(path, lines=40):
    try:
        text = Path(path).read_text(errors="replace").splitlines()
    except OSError as exc:
        return f"({path}: {exc.strerror})"
    return "\n".join(text[-lines:]) or f"({path} is empty)"


class LocalSlurmCluster:
    def __init__(self, root):
        self.root = Path(root)
        self.host = socket.gethostname().split(".")[0]
        self.conf = self.root / "slurm.conf"
        self.munge_dir = self.root / "munge"
        self.pid_files = {}  # daemon name -> pid file, in start order
        self.logs = {"munged": self.munge_dir / "munged.log", "slurmctld": self.root / "slurmctld.log",
                     "slurmd": self.root / "slurmd.log"}

    @property
    def env(self):
        """The environment for sbatch, squeue, ...: this cluster's slurm.conf."""
        return dict(os.environ, SLURM_CONF=str(self.conf))

    # -- start --------------------------------------------------------------

    def start(self, timeout=30.0):
        # munged refuses a socket folder that is not searchable by everyone
        # or that others can write to.
        self.root.chmod(0o755)
        for sub in ("munge", "state", "spool"):
            (self.root / sub).mkdir(mode=0o755, exist_ok=True)
        key = self.munge_dir / "munge.key"
        self._run_daemon("mungekey", ["/usr/sbin/mungekey", "--create", f"--keyfile={key}"], pid_file=None)
        socket_path = self.munge_dir / "munge.socket"
        self._run_daemon("munged", [MUNGED, f"--key-file={key}", f"--socket={socket_path}",
                                    f"--pid-file={self.munge_dir / 'munged.pid'}", f"--log-file={self.logs['munged']}",
                                    f"--seed-file={self.munge_dir / 'munged.seed'}"],
                         pid_file=self.munge_dir / "munged.pid")
        ctld_port, slurmd_port = free_ports(2)
        self.conf.write_text(slurm_conf(self.root, self.host, os.cpu_count(), ctld_port, slurmd_port, socket_path))
        # -i: a fresh state folder has no state to recover.
        self._run_daemon("slurmctld", [SLURMCTLD, "-f", str(self.conf), "-i"], pid_file=self.root / "slurmctld.pid")
        self._run_daemon("slurmd", [SLURMD, "-f", str(self.conf)], pid_file=self.root / "slurmd.pid")
        self._wait_for_idle_node(timeout)

    def _run_daemon(self, name, cmd, pid_file):
        """Runs a daemon's start command (it forks and writes its pid file) and
        waits for the pid file; fails with the daemon's log otherwise."""
        done = subprocess.run(cmd, capture_output=True, text=True, env=self.env, timeout=30)
        if pid_file is not None:
            self.pid_files[name] = pid_file
        if done.returncode != 0:
            raise ClusterError(f"{name} did not start ({' '.join(cmd)} exited {done.returncode}):\n"
                               f"{done.stdout}{done.stderr}\n--- {name} log:\n{read_log(self.logs.get(name, ''))}")
        deadline = time.monotonic() + 10.0
        while pid_file is not None and not self._pid(pid_file):
            if time.monotonic() > deadline:
                raise ClusterError(f"{name} wrote no pid file {pid_file}\n--- {name} log:\n"
                                   f"{read_log(self.logs.get(name, ''))}")
            time.sleep(0.05)

    def _wait_for_idle_node(self, timeout):
        deadline = time.monotonic() + timeout
        state = ""
        while time.monotonic() < deadline:
            done = subprocess.run(["sinfo", "-h", "-N", "-o", "%T"], capture_output=True, text=True, env=self.env)
            state = (done.stdout + done.stderr).strip()
            if done.returncode == 0 and state.startswith("idle"):
                return
            time.sleep(0.2)
        raise ClusterError(f"the node did not become idle in {timeout:.0f} s (sinfo: {state!r})\n"
                           + self.logs_text())

    def logs_text(self):
        return "\n".join(f"--- {name} log:\n{read_log(path)}" for name, path in self.logs.items())

    # -- jobs ---------------------------------------------------------------

    def wait_for_jobs(self, job_ids, timeout):
        """Waits until none of the jobs is pending or running; returns
        {job id (array tasks as 12_3): (state, exit code)}."""
        deadline = time.monotonic() + timeout
        ids = ",".join(job_ids)
        while True:
            queued = subprocess.run(["squeue", "-h", "-j", ids, "-o", "%i %T"], capture_output=True, text=True,
                                    env=self.env)
            if queued.returncode == 0 and not queued.stdout.strip():
                break
            if time.monotonic() > deadline:
                raise ClusterError(f"jobs {ids} still queued after {timeout:.0f} s:\n{queued.stdout}{queued.stderr}\n"
                                   + self.logs_text())
            time.sleep(0.5)
        return {job: state for job_id in job_ids for job, state in self.job_states(job_id).items()}

    def job_states(self, job_id):
        shown = subprocess.run(["scontrol", "-o", "show", "job", job_id], capture_output=True, text=True,
                               env=self.env)
        states = {}
        for line in shown.stdout.splitlines():
            fields = dict(f.split("=", 1) for f in line.split() if "=" in f)
            task = fields.get("ArrayTaskId")
            name = f"{fields.get('ArrayJobId')}_{task}" if task else fields.get("JobId")
            states[name] = (fields.get("JobState"), fields.get("ExitCode"))
        return states

    # -- stop ---------------------------------------------------------------

    def stop(self):
        """Cancels what is left of the jobs, then stops every daemon this
        cluster started (slurmd, slurmctld, munged), each by its pid file:
        SIGTERM, then SIGKILL after 10 s."""
        if self.pid_files.get("slurmctld"):
            subprocess.run(["scancel", "--full", "--user=root"], capture_output=True, env=self.env, timeout=30)
        for name in reversed(list(self.pid_files)):
            pid = self._pid(self.pid_files[name])
            if pid:
                self._terminate(pid)

    @staticmethod
    def _pid(pid_file):
        try:
            return int(Path(pid_file).read_text().strip() or 0)
        except (OSError, ValueError):
            return 0

    @staticmethod
    def _terminate(pid):
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.05)
        os.kill(pid, signal.SIGKILL)
