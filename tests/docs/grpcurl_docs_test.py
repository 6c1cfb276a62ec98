#!/usr/bin/env python3
"""The docs show what grpcurl prints: runs them against live services.

With a `grpcurl` on PATH, starts the services from BUILD_DIR on free loopback
ports (a fresh SQLite database, the simulated robot and camera) and:
  - runs every grpcurl line of the README's "grpcurl" section; each must
    exit 0;
  - runs every `$ grpcurl ...` command (or `$ (...grpcurl...) | grpcurl ...`
    pipeline, through bash) of the ```console sessions in the
    docs listed in SESSIONS, in order, and compares what it prints (stdout,
    then stderr) with the lines shown under it. A `…` in a shown line matches
    any text; a line that is only `…` matches any number of lines. A shown
    output starting with `ERROR:` expects a non-zero exit status, any other
    expects 0.
The addresses 127.0.0.1:5005N of the docs are rewritten to the test's ports.
Without grpcurl it says so on one line and exits 77, which CTest reports as
skipped, never as passed.

usage: grpcurl_docs_test.py SOURCE_DIR BUILD_DIR
"""
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
import time

SESSIONS = [
    "docs/api.md", "docs/robot.md", "docs/haptic.md", "docs/perception.md"
]

# Default port of each service in the docs, its binary, health name, flags.
SERVICES = [
    (50051, "services/bandit/bitewise-bandit", "bitewise.v1.BanditService",
     ["--db", "{tmp}/bandit.db", "--create"]),
    (50052, "services/perception/bitewise-perception",
     "bitewise.v1.PerceptionService", []),
    (50053, "services/haptic/bitewise-haptic", "bitewise.v1.HapticService", []),
    (50054, "services/robot/bitewise-robot", "bitewise.v1.RobotService",
     ["--backend", "sim", "--seed", "1"]),
    (50055, "services/camera/bitewise-camera", "bitewise.v1.CameraService",
     ["--source", "sim"]),
]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Services:
    """The services on free ports; restartable with a fresh database."""

    def __init__(self, build):
        self.build = build
        # Under scripts/test.sh, inside the build tree (TEST_TMPDIR).
        self.tmp = tempfile.mkdtemp(prefix="grpcurl_docs_",
                                    dir=os.environ.get("TEST_TMPDIR") or None)
        self.ports = {}
        self.processes = []

    def start(self):
        for default_port, binary, name, flags in SERVICES:
            port = free_port()
            self.ports[default_port] = port
            args = [os.path.join(self.build, binary), "--listen",
                    f"127.0.0.1:{port}"]
            args += [f.format(tmp=self.tmp) for f in flags]
            log = open(os.path.join(self.tmp, os.path.basename(binary) + ".log"),
                       "ab")
            self.processes.append(subprocess.Popen(
                args, stdout=log, stderr=subprocess.STDOUT))
            probe = [os.path.join(self.build, "clients/health/bitewise-health"),
                     "--address", f"127.0.0.1:{port}", "--service", name,
                     "--timeout_s", "60"]
            if subprocess.run(probe, capture_output=True).returncode != 0:
                raise RuntimeError(f"{name} did not become healthy; see {log.name}")

    def stop(self):
        for p in self.processes:
            p.terminate()
        for p in self.processes:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
        self.processes = []
        db = os.path.join(self.tmp, "bandit.db")
        for path in (db, db + "-wal", db + "-shm", db + ".contexts"):
            if os.path.exists(path):
                os.remove(path)

    def rewrite(self, command):
        return re.sub(r"127\.0\.0\.1:(5005[1-5])",
                      lambda m: f"127.0.0.1:{self.ports[int(m.group(1))]}",
                      command)


def run(services, command, source):
    """Runs `command` (`< FILE` reads FILE, relative to the repository)."""
    if "|" in command:  # a pipeline, as a shell runs it
        done = subprocess.run(["bash", "-c", services.rewrite(command)],
                              capture_output=True, text=True, timeout=120)
        return done.returncode, (done.stdout + done.stderr).rstrip("\n").split("\n")
    stdin = None
    if " < " in command:
        command, path = command.rsplit(" < ", 1)
        stdin = open(os.path.join(source, path.strip()))
    argv = shlex.split(services.rewrite(command), comments=True)
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120,
                          stdin=stdin)
    return done.returncode, (done.stdout + done.stderr).rstrip("\n").split("\n")


def line_matches(pattern, line):
    parts = [re.escape(p) for p in pattern.rstrip().split("…")]
    return re.fullmatch(".*".join(parts), line.rstrip()) is not None


def output_matches(shown, actual):
    """`shown` lines against `actual` lines, `…` lines matching any run."""
    if not shown:
        return not actual or actual == [""]
    head = shown[0]
    if head.strip() == "…":
        return any(output_matches(shown[1:], actual[i:])
                   for i in range(len(actual) + 1))
    return (bool(actual) and line_matches(head, actual[0])
            and output_matches(shown[1:], actual[1:]))


def readme_commands(source):
    text = open(os.path.join(source, "README.md")).read()
    section = text.split("## grpcurl", 1)[1]
    block = section.split("```sh", 1)[1].split("```", 1)[0]
    commands, current = [], ""
    for line in block.split("\n"):
        current += line.rstrip("\\").strip() + " "
        if not line.rstrip().endswith("\\"):
            if current.strip().startswith("grpcurl"):
                commands.append(current.strip())
            current = ""
    return commands


def session_steps(path):
    """(command, shown output lines) of every ```console block's `$ grpcurl`."""
    steps = []
    in_block, command, shown, continuing = False, None, [], False
    for line in open(path).read().split("\n"):
        if line.startswith("```console"):
            in_block = True
            continue
        if in_block and line.startswith("```"):
            if command:
                steps.append((command, shown))
            in_block, command, shown = False, None, []
            continue
        if not in_block:
            continue
        if continuing:
            command += " " + line.rstrip("\\").strip()
            continuing = line.endswith("\\")
        elif line.startswith("$ "):
            if command:
                steps.append((command, shown))
            command, shown = line[2:].rstrip("\\").strip(), []
            continuing = line.endswith("\\")
        else:
            shown.append(line)
    return [(c, s[:-1] if s and s[-1] == "" else s) for c, s in steps
            if "grpcurl" in c]


def main():
    source, build = sys.argv[1], sys.argv[2]
    if shutil.which("grpcurl") is None:
        print("SKIPPED: no grpcurl on PATH, so the README's and docs' grpcurl "
              "lines were not checked")
        return 77
    failures = []
    services = Services(build)
    try:
        services.start()
        for doc in SESSIONS:
            for command, shown in session_steps(os.path.join(source, doc)):
                status, actual = run(services, command, source)
                expect_error = bool(shown) and shown[0] == "ERROR:"
                if (status != 0) != expect_error or not output_matches(shown, actual):
                    failures.append(f"{doc}: {command}\n  exit {status}; printed:\n    "
                                    + "\n    ".join(actual) + "\n  shown:\n    "
                                    + "\n    ".join(shown))
                else:
                    print(f"ok   {doc}: {command[:100]}")
        # The README's lines on a fresh database.
        services.stop()
        services.start()
        for command in readme_commands(source):
            status, actual = run(services, command, source)
            if status != 0:
                failures.append(f"README.md: {command}\n  exit {status}:\n    "
                                + "\n    ".join(actual))
            else:
                print(f"ok   README.md: {command[:100]}")
    finally:
        services.stop()
    for failure in failures:
        print(f"FAIL {failure}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
