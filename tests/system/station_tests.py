"""Station tests: the edge daemon under systemd in the booted guest, on real kernel
interfaces, driven from the host (docs/system-tests.md, "The station").

The guest side is tests/system/guest/station/setup.sh (run once per boot: the package's
files, gpio-sim, vivid loopback fed the rendered door, calibration, systemctl start) and
the guest tools vivid_feeder and valve_probe; the host side is here: the robot
simulator (`dentmark robot-sim`, reached by the guest at 10.0.2.2), `dentmark detect`
and `dentmark send --wait` through the forward of the daemon's link port. Every check
compares what the host was told with what the kernel saw in the guest (the valve's
gpio-sim line), what the daemon wrote in its StateDirectory and what the robot
simulator recorded.

  ready  systemctl restart: READY=1 (Type=notify), ActiveState, StatusText; `dentmark
         status` through the forward
  job    one whole job: every markable defect marked, one valve pulse each on the
         gpio-sim line, one journal 'spray' line each, one robot spray each
  estop  e-stop through gpio-sim's pull as the valve opens, over several jobs: valve
         low within 10 ms, the job reported emergency_stop, the robot stopped there
  kill   `systemctl kill -s KILL` after the first mark: systemd restarts the daemon,
         it comes up with the valve low and the robot still, nothing sprayed twice
"""

import json
import os
import re
import shutil
import statistics
import subprocess
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUN = "/run/dentmark-station"
PANEL = "door-FL-0001"
ESTOP_LIMIT_MS = 10.0
SEQUENCE = ["--seconds", "20", "--fps", "2", "--start-offset", "-0.1", "--width", "640", "--height", "480", "--focal", "870"]


class Failure(Exception):
    pass


def say(msg):
    print(f"station: {msg}", flush=True)


def check(cond, what):
    if not cond:
        raise Failure(what)
    say(f"ok: {what}")


class Station:
    def __init__(self, state, guest, cli, con):
        self.state, self.guest, self.cli, self.con = state, guest, cli, con
        self.src, self.build = guest["source"], guest["build"]
        self.link = f"127.0.0.1:{guest['link_port']}"
        self.work = state / "station"
        self.work.mkdir(exist_ok=True)

    # ---- guest -------------------------------------------------------------------
    def sh(self, command, timeout=120, ok=True):
        """Runs a command line in the guest; returns its output (fails unless 'ok' is
        False or it exits 0)."""
        rc, out = self.con.run(command, timeout)
        if rc is None:
            raise Failure(f"guest: no answer within {timeout} s to: {command}")
        if ok and rc != 0:
            raise Failure(f"guest: exit {rc}: {command}\n{out}")
        return out

    def env(self):
        return dict(
            line.split("=", 1) for line in self.sh(f"cat {RUN}/env").splitlines() if "=" in line
        )

    def show(self, *props):
        out = self.sh(f"systemctl show -p {','.join(props)} dentmark-edge")
        return dict(line.split("=", 1) for line in out.splitlines() if "=" in line)

    # ---- host --------------------------------------------------------------------
    def host(self, *args, timeout=120):
        r = subprocess.run([self.cli, *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           timeout=timeout)  # fmt: skip
        return r.returncode, r.stdout

    def prepare(self):
        """The host's share of the setup: the rendered door and the libraries the guest lacks."""
        seq = self.state / "seq"
        if not (seq / "frames.csv").exists():
            t0 = time.monotonic()
            shutil.rmtree(seq, ignore_errors=True)
            rc, out = self.host("synth", "stereo", "--out", str(seq), *SEQUENCE, timeout=600)
            if rc != 0:
                raise Failure(f"dentmark synth stereo failed:\n{out}")
            say(f"rendered the door's sequence ({' '.join(SEQUENCE)}) in {time.monotonic() - t0:.1f} s")
        missing = self.sh(f"ldd {self.build}/firmware/app/dentmark-edge | awk '/not found/ {{print $1}}'").split()
        if missing:
            sysroot = sysroot_of(Path(self.build))
            lib = self.state / "lib"
            lib.mkdir(exist_ok=True)
            for name in missing:
                path = sysroot / "usr/lib/aarch64-linux-gnu" / name
                if not path.exists():
                    raise Failure(f"{name}: needed by dentmark-edge, absent from the guest and from {sysroot}")
                shutil.copy(path.resolve(), lib / name)
            say(f"libraries the guest image lacks, from the arm64 sysroot: {' '.join(missing)}")

    def setup(self, restart=False):
        """The guest as an edge box with the daemon running (setup.sh); returns its output."""
        if not self.guest_ready():
            self.prepare()
        out = self.sh(
            f"bash {self.src}/tests/system/guest/station/setup.sh {self.src} {self.build} {self.state} "
            f"{self.guest['robot_port']}{' --restart' if restart else ''}",
            timeout=400,
        )
        print(out.rstrip(), flush=True)
        return out

    def guest_ready(self):
        rc, _ = self.con.run(f"test -f {RUN}/env", 30)
        return rc == 0

    def robot_sim(self, record):
        """`dentmark robot-sim` on the port the guest's board file names."""
        log = open(self.work / (Path(record).stem + ".robot.log"), "w")
        proc = subprocess.Popen(
            [self.cli, "robot-sim", "--host", "127.0.0.1", "--port", str(self.guest["robot_port"]),
             "--heartbeat-timeout", "2", "--record", str(record)],
            stdout=log, stderr=subprocess.STDOUT,
        )  # fmt: skip
        deadline = time.monotonic() + 10
        while "listening on" not in (self.work / (Path(record).stem + ".robot.log")).read_text():
            if proc.poll() is not None or time.monotonic() > deadline:
                raise Failure("dentmark robot-sim did not start: " + (self.work / (Path(record).stem + ".robot.log")).read_text())
            time.sleep(0.05)
        return proc

    @staticmethod
    def stop_robot(proc, record):
        proc.terminate()
        proc.wait(20)
        return json.loads(Path(record).read_text())

    def defect_list(self, job):
        """`dentmark detect` of the rendered scan, stamped with this moment as the scan time."""
        scan = self.work / "door.ply"
        if not scan.exists():
            rc, out = self.host("synth", "scan", "--out", str(scan), "--truth", str(self.work / "truth.json"),
                                "--seed", "5", "--defects", "6", timeout=300)  # fmt: skip
            if rc != 0:
                raise Failure(f"dentmark synth scan failed:\n{out}")
        dml = self.work / f"job{job}.dml"
        rc, out = self.host("detect", str(scan), "--out", str(dml), "--json", str(dml.with_suffix(".json")),
                            "--panel", PANEL, "--job", str(job), "--scan-time", f"{time.time():.6f}", timeout=300)  # fmt: skip
        if rc != 0:
            raise Failure(f"dentmark detect failed:\n{out}")
        listed = json.loads(dml.with_suffix(".json").read_text())["defects"]
        markable = [d["id"] for d in listed if d["class"] in ("dent", "bump", "hole")]
        return dml, markable, len(listed)

    def send(self, dml, marks, job_timeout=240):
        """`dentmark send --wait` in the background; returns the process (stderr in a file)."""
        err = open(Path(marks).with_suffix(".err"), "w")
        return subprocess.Popen(
            [self.cli, "send", str(dml), "--to", self.link, "--wait", "--job-timeout", str(job_timeout),
             "--json", str(marks)],
            stdout=subprocess.PIPE, stderr=err, text=True,
        )  # fmt: skip

    def journal(self, job):
        return self.sh(f"cat /var/lib/dentmark/jobs/{job}/journal").splitlines()


def unique_job(test, k=0):
    """A job id no earlier run on this guest used (a used id is refused with other content)."""
    return (int(time.time()) % 100000) * 1000 + test * 100 + k


def sysroot_of(build):
    m = re.search(r"^DENTMARK_SYSROOT:PATH=(.*)$", (build / "CMakeCache.txt").read_text(), re.M)
    if not m:
        raise Failure(f"{build}/CMakeCache.txt names no DENTMARK_SYSROOT")
    return Path(m.group(1))


def pulses_of(text):
    return [float(line.split()[3]) for line in text.splitlines() if line.startswith("pulse ")]


def spray_ids(journal):
    return [int(line.split()[1]) for line in journal if line.startswith("spray ")]


def outcome_counts(marks):
    counts = {}
    for m in marks["marks"]:
        key = m["outcome"] if m["outcome"] == "marked" else f"{m['outcome']}/{m['reason']}"
        counts[key] = counts.get(key, 0) + 1
    return counts


# ---- tests ---------------------------------------------------------------------------
def test_ready(st):
    out = st.setup(restart=True)
    m = re.search(r"READY=1 ([0-9.]+) s after", out)
    check(m is not None, "systemctl restart returned after the daemon's READY=1")
    props = st.show("ActiveState", "SubState", "Type", "StatusText", "User")
    check(props.get("Type") == "notify", f"Type=notify ({props.get('Type')})")
    check(props.get("ActiveState") == "active" and props.get("SubState") == "running",
          f"ActiveState={props.get('ActiveState')} SubState={props.get('SubState')}")  # fmt: skip
    check(props.get("StatusText", "").startswith("idle"), f"StatusText={props.get('StatusText')!r}")
    who = st.sh("ps -o user= -C dentmark-edge").split()
    check(who == ["dentmark"], f"the daemon runs as the dentmark user ({who})")
    t0 = time.monotonic()
    rc, out = st.host("status", st.link, timeout=30)
    print(out.rstrip())
    check(rc == 0 and re.search(r": idle, faults: none$", out, re.M) is not None,
          f"dentmark status {st.link} (the forward to the guest's 7878) answers idle in {time.monotonic() - t0:.2f} s")  # fmt: skip
    say(f"figures: READY=1 {m.group(1)} s after systemctl restart; boot to root shell {st.guest['boot_s']:.1f} s")
    return True


def test_job(st):
    st.setup()
    env = st.env()
    record = st.work / "job.robot.json"
    robot = st.robot_sim(record)
    try:
        st.sh(f"rm -f {RUN}/pulses-job; systemctl stop dentmark-valve-watch 2>/dev/null; systemd-run --quiet --unit=dentmark-valve-watch --collect "
              f"{st.build}/tests/system/valve_probe watch {env['VALVE_VALUE']} {RUN}/pulses-job")  # fmt: skip
        job = unique_job(1)
        dml, markable, listed = st.defect_list(job)
        t0 = time.monotonic()
        sender = st.send(dml, st.work / "job.marks.json")
        out, _ = sender.communicate(timeout=300)
        t_job = time.monotonic() - t0
        print(out.rstrip())
        st.sh("systemctl stop dentmark-valve-watch")
    finally:
        rec = st.stop_robot(robot, record)
    marks = json.loads((st.work / "job.marks.json").read_text())
    pulses = pulses_of(st.sh(f"cat {RUN}/pulses-job"))
    sprays = spray_ids(st.journal(job))
    counts = outcome_counts(marks)
    say(f"job {job}: {listed} defects listed ({len(markable)} markable), outcomes {counts}, {len(pulses)} valve "
        f"pulses ({', '.join(f'{p:.0f}' for p in pulses)} ms), journal sprays {sprays}, robot sprays "
        f"{len(rec['sprays'])}; {t_job:.1f} s from send to the last report")  # fmt: skip
    check(sender.returncode == 0, f"dentmark send --wait exit 0 ({sender.returncode})")
    check(marks["complete"] and counts.get("marked", 0) == len(markable) and len(marks["marks"]) == listed,
          f"every markable defect marked ({counts.get('marked', 0)} of {len(markable)})")  # fmt: skip
    errors = [m["estimated_error"] for m in marks["marks"] if m["outcome"] == "marked"]
    say(f"the daemon's estimated marking errors: {', '.join(f'{1e3 * e:.2f}' for e in errors)} mm")
    check(len(pulses) == len(markable), f"one valve pulse per marked defect on the gpio-sim line ({len(pulses)})")
    check(all(120 <= p <= 250 for p in pulses), "each pulse the planned 150 ms (120..250 ms as polled)")
    check(sorted(sprays) == sorted(markable), "the journal has one 'spray' line per markable defect")
    check(len(rec["sprays"]) == len(markable), f"the robot simulator sprayed once per defect ({len(rec['sprays'])})")
    say(f"figures: job of {len(markable)} defects {t_job:.1f} s; pulses {min(pulses):.0f}..{max(pulses):.0f} ms")
    return True


def test_estop(st, trials=int(os.environ.get("DENTMARK_ESTOP_TRIALS", "3"))):
    st.setup()
    env = st.env()
    latencies = []
    for k in range(trials):
        job = unique_job(2, k)
        record = st.work / f"estop{k}.robot.json"
        robot = st.robot_sim(record)
        try:
            st.sh(f"rm -f {RUN}/estop{k}; systemctl stop dentmark-estop-probe 2>/dev/null; systemd-run --quiet --unit=dentmark-estop-probe --collect "
                  f"-p StandardOutput=file:{RUN}/estop{k} {st.build}/tests/system/valve_probe estop "
                  f"{env['VALVE_VALUE']} {env['ESTOP_PULL']} {env['ESTOP_PRESSED']} 200")  # fmt: skip
            dml, markable, listed = st.defect_list(job)
            sender = st.send(dml, st.work / f"estop{k}.marks.json")
            out, _ = sender.communicate(timeout=300)
            print(out.rstrip())
            # The job is over: a probe still waiting never saw the valve open.
            st.sh("sleep 1; systemctl stop dentmark-estop-probe 2>/dev/null; true", timeout=60)
            probe = st.sh(f"cat {RUN}/estop{k}")
            status = st.show("StatusText")["StatusText"]
        finally:
            st.sh(f"echo {env['ESTOP_RELEASED']} > {env['ESTOP_PULL']}", ok=False)
            rec = st.stop_robot(robot, record)
        print(probe.rstrip())
        m = re.search(r"valve low ([0-9.]+) ms after", probe)
        check(m is not None, f"trial {k}: the e-stop was pulled with the valve open and the valve closed")
        latencies.append(float(m.group(1)))
        marks = json.loads((st.work / f"estop{k}.marks.json").read_text())
        counts = outcome_counts(marks)
        say(f"trial {k}: job {job} outcomes {counts}; daemon status then {status!r}")
        check(sender.returncode == 3, f"trial {k}: dentmark send --wait exit 3, not all marked ({sender.returncode})")
        # Outcomes decided before the e-stop stand (skipped); nothing marked, the rest
        # failed/emergency_stop.
        check(marks["complete"] and counts.get("failed/emergency_stop", 0) >= 1 and not counts.get("marked"),
              f"trial {k}: nothing marked, the open defects reported failed/emergency_stop")  # fmt: skip
        # The robot stopped where it sprayed: no retract, no next approach.
        sprays = rec["sprays"]
        check(len(sprays) == 1, f"trial {k}: the robot simulator saw one spray command ({len(sprays)})")
        t_spray = sprays[0]["time"]
        at = [s for s in rec["trajectory"] if s["time"] >= t_spray]
        moved = max(
            (sum((a - b) ** 2 for a, b in zip(s["tip"]["t"], at[0]["tip"]["t"])) ** 0.5 for s in at), default=0.0
        )
        check(moved < 0.002, f"trial {k}: the robot's tip moved {1e3 * moved:.2f} mm after the spray began (< 2 mm)")
    lat = sorted(latencies)
    say(f"figures: e-stop pull write -> valve line low over {trials} jobs: median {statistics.median(lat):.3f} ms, "
        f"max {lat[-1]:.3f} ms ({', '.join(f'{x:.3f}' for x in latencies)})")  # fmt: skip
    check(lat[-1] <= ESTOP_LIMIT_MS, f"every trial within {ESTOP_LIMIT_MS:.0f} ms")
    return True


def test_kill(st):
    st.setup()
    env = st.env()
    before = int(st.show("NRestarts")["NRestarts"])
    record = st.work / "kill.robot.json"
    robot = st.robot_sim(record)
    job = unique_job(3)
    marks_path = st.work / "kill.marks.json"
    try:
        st.sh(f"rm -f {RUN}/pulses-kill; systemctl stop dentmark-valve-watch 2>/dev/null; systemd-run --quiet --unit=dentmark-valve-watch --collect "
              f"{st.build}/tests/system/valve_probe watch {env['VALVE_VALUE']} {RUN}/pulses-kill")  # fmt: skip
        dml, markable, listed = st.defect_list(job)
        sender = st.send(dml, marks_path)
        err = marks_path.with_suffix(".err")
        deadline = time.monotonic() + 240
        while ": marked" not in err.read_text():
            if sender.poll() is not None or time.monotonic() > deadline:
                raise Failure(f"no defect marked before the kill:\n{err.read_text()}")
            time.sleep(0.05)
        old_pid = st.show("MainPID")["MainPID"]
        t_kill = time.monotonic()
        st.sh("systemctl kill -s KILL dentmark-edge")
        valve_after_kill = st.sh(f"cat {env['VALVE_VALUE']}").strip()
        say(f"killed pid {old_pid} after {err.read_text().count(': marked')} mark(s); valve line then {valve_after_kill}")
        while True:
            props = st.show("ActiveState", "SubState", "NRestarts", "MainPID", "StatusText")
            if int(props["NRestarts"]) > before and props["ActiveState"] == "active" and props["SubState"] == "running":
                break
            if time.monotonic() - t_kill > 330:
                raise Failure(f"systemd did not bring the daemon back within 330 s: {props}")
            time.sleep(0.2)
        t_back = time.monotonic() - t_kill
        valve_after_restart = st.sh(f"cat {env['VALVE_VALUE']}").strip()
        out, _ = sender.communicate(timeout=300)
        print(out.rstrip())
        st.sh("systemctl stop dentmark-valve-watch")
        restart_log = st.sh(f"journalctl -u dentmark-edge -o cat --no-pager _PID={props['MainPID']} | head -20")
    finally:
        rec = st.stop_robot(robot, record)
    print(restart_log.rstrip())
    marks = json.loads(marks_path.read_text())
    counts = outcome_counts(marks)
    pulses = pulses_of(st.sh(f"cat {RUN}/pulses-kill"))
    journal = st.journal(job)
    sprays = spray_ids(journal)
    marked = [m["defect_id"] for m in marks["marks"] if m["outcome"] == "marked"]
    say(f"job {job}: outcomes {counts}; journal sprays {sprays}; {len(pulses)} valve pulses; robot sprays "
        f"{len(rec['sprays'])}; back (active, running, READY=1) {t_back:.1f} s after the kill")  # fmt: skip
    check(int(props["NRestarts"]) == before + 1 and props["MainPID"] != old_pid,
          f"systemd restarted the daemon (NRestarts {before} -> {props['NRestarts']}, pid {old_pid} -> {props['MainPID']})")  # fmt: skip
    check(valve_after_kill == "0" and valve_after_restart == "0", "the valve line low after the kill and after the restart")
    check(f"job {job} was interrupted" in restart_log, "the restarted daemon ended the interrupted job")
    check(sender.returncode == 3, f"dentmark send --wait rode over the restart and exited 3 ({sender.returncode})")
    ids = [m["defect_id"] for m in marks["marks"]]
    check(marks["complete"] and len(ids) == len(set(ids)) == listed, "every defect has exactly one outcome")
    # Outcomes decided before the kill stand (marked, or skipped); those still open when
    # the daemon died are reported failed/aborted by the restarted one.
    check(marked and counts.get("failed/aborted", 0) >= 1,
          f"{len(marked)} marked before the kill, {counts.get('failed/aborted', 0)} reported failed/aborted after it")  # fmt: skip
    check(len(sprays) == len(set(sprays)), f"no defect twice in the journal's spray lines ({sprays})")
    check(set(marked) <= set(sprays) and len(sprays) <= len(marked) + 1, "a spray line for each marked defect, at most one more")
    check(len(pulses) in (len(sprays), len(sprays) - 1) and len(pulses) >= len(marked),
          f"valve pulses on the gpio-sim line ({len(pulses)}) match the journal's sprays ({len(sprays)})")  # fmt: skip
    check(abs(len(rec["sprays"]) - len(pulses)) <= 1, "robot spray commands match the valve pulses")
    # After the kill nothing heartbeats the robot: its watchdog (2 s) stops it, and the
    # restarted daemon must not move it.
    t_kill_robot = t_kill + 2.0 + 1.0
    late = [s for s in rec["trajectory"] if s["time"] > t_kill_robot and s["speed"] > 1e-6]
    check(not late, f"the robot did not move from 3 s after the kill on ({len(late)} moving samples)")
    say(f"figures: restart {t_back:.1f} s from SIGKILL to active again; {len(pulses)} pulses for {len(marked)} marked")
    return True


TESTS = {"ready": test_ready, "job": test_job, "estop": test_estop, "kill": test_kill}


def run(name, state, guest, cli, con):
    if name not in TESTS:
        raise Failure(f"no station test '{name}' (one of {', '.join(TESTS)})")
    return TESTS[name](Station(state, guest, cli, con))
