#!/usr/bin/env python3
"""Hostile-input suite for the walkgraph CLI (standard library only).

    python3 tests/hostile_inputs_test.py --cli build/tools/walkgraph --source-dir . \
        [--keep] [-k SUBSTRING] [-v] [-j JOBS]

Every case gets a fresh sandbox (tempfile.mkdtemp) with its own HOME (<sandbox>/home), builds
its inputs there (a copy of tests/data/walks/valid_small or datasets/plaza1 with one thing
mutated, or files written from scratch), runs the CLI with cwd inside the sandbox and a timeout,
and checks:
  1. the exit code (1 for errors, never a signal / abort / segfault; 0 where accepted);
  2. stderr against the case's regex (errors print "walkgraph: <message>"; messages about file
     content name "path:line:");
  3. nothing in the sandbox changed except the intended output (only when success is expected):
     type, size, sha256 / symlink target and permission bits of every entry;
  4. no temporary left anywhere ("walkgraph-tmp", "walkgraph-old", ".tmp-");
  5. stderr shorter than 2000 characters.
Exit status 0 only when every case passes; one line per failing case, then "N passed, M failed".

The contract the cases check (output-folder safety, special files, YAML, CSV, CLI numbers,
simulator overrides, study manifests, signals) is spelled out next to each group below.
"""

import argparse
import dataclasses
import errno
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, List, Optional, Sequence, Tuple, Union

MARKER = ".walkgraph-output"
TEMP_PATTERNS = ("walkgraph-tmp", "walkgraph-old", ".tmp-")
MAX_STDERR = 2000
AS_LIMIT_KB = 4 * 1024 * 1024  # RLIMIT_AS of every CLI run: 4 GB (via `ulimit -v`)
NOBODY = 65534
IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0

ARGS = None  # parsed command line


# --------------------------------------------------------------------------------------- results

@dataclasses.dataclass
class Result:
    rc: Optional[int]  # None: hung (killed after the timeout)
    stdout: str
    stderr: str
    elapsed: float
    hung: bool = False


class SetupError(Exception):
    pass


def describe_rc(rc):
    if rc is None:
        return "hung"
    if rc < 0:
        try:
            return "%d (killed by %s)" % (rc, signal.Signals(-rc).name)
        except ValueError:
            return "%d (killed by signal %d)" % (rc, -rc)
    if rc in (134, 139):
        return "%d (%s)" % (rc, "abort" if rc == 134 else "segfault")
    return str(rc)


# --------------------------------------------------------------------------------------- running

_cli_gone = threading.Event()


def wait_for_cli(limit_s=150.0):
    """The binary is rebuilt now and then: wait for it to come back (once it stayed away for
    limit_s, every later case fails at once instead of waiting again)."""
    t0 = time.time()
    while not (os.path.isfile(ARGS.cli) and os.access(ARGS.cli, os.X_OK)):
        if _cli_gone.is_set() or time.time() - t0 > limit_s:
            _cli_gone.set()
            return False
        time.sleep(2.0)
    return True


def spawn(argv, cwd, home, as_nobody=False, limit_as=True):
    """Starts the CLI (in its own session) and returns the Popen."""
    cmd = [ARGS.cli] + list(argv)
    if limit_as and not ARGS.sanitized:  # ASan reserves terabytes of address space
        cmd = ["/bin/sh", "-c", 'ulimit -v %d 2>/dev/null; exec "$@"' % AS_LIMIT_KB,
               "walkgraph-sh"] + cmd
    env = dict(os.environ)
    env["HOME"] = home
    env["LC_ALL"] = "C"
    kwargs = dict(cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                  stderr=subprocess.PIPE, start_new_session=True)
    if as_nobody:
        kwargs.update(user=NOBODY, group=NOBODY, extra_groups=[])
    t0 = time.time()
    while True:
        if not wait_for_cli():
            raise SetupError("CLI %s missing for more than 150 s" % ARGS.cli)
        try:
            return subprocess.Popen(cmd, **kwargs)
        except OSError as e:  # ETXTBSY / ENOENT while the linker writes the binary
            if e.errno in (errno.ETXTBSY, errno.ENOENT) and time.time() - t0 < 150:
                time.sleep(2.0)
                continue
            raise


def finish(p, timeout, t0):
    try:
        out, err = p.communicate(timeout=timeout * ARGS.time_scale)
        hung = False
    except subprocess.TimeoutExpired:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        out, err = p.communicate()
        hung = True
    return Result(None if hung else p.returncode, out.decode("utf-8", "replace"),
                  err.decode("utf-8", "replace"), time.time() - t0, hung)


def run_cli(argv, cwd, home, timeout=60.0, as_nobody=False, limit_as=True):
    t0 = time.time()
    p = spawn(argv, cwd, home, as_nobody, limit_as)
    return finish(p, timeout, t0)


# --------------------------------------------------------------------------------------- snapshot

def sha256_of(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(1 << 20)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def entry_of(full):
    st = os.lstat(full)
    mode = stat.S_IMODE(st.st_mode)
    if stat.S_ISLNK(st.st_mode):
        return ("link", os.readlink(full))
    if stat.S_ISDIR(st.st_mode):
        return ("dir", mode)
    if stat.S_ISREG(st.st_mode):
        try:
            digest = sha256_of(full)
        except OSError as e:
            digest = "unreadable: %s" % e
        return ("file", st.st_size, digest, mode)
    if stat.S_ISFIFO(st.st_mode):
        return ("fifo", mode)
    if stat.S_ISSOCK(st.st_mode):
        return ("socket", mode)
    if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode):
        return ("device", st.st_rdev)
    return ("other", st.st_mode)


def snapshot(root):
    """relative path -> (type, size, sha256 | symlink target, mode); "." is the root itself."""
    snap = {}
    if not os.path.lexists(root):
        return snap
    snap["."] = entry_of(root)
    if snap["."][0] != "dir":
        return snap
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            full = os.path.join(dirpath, name)
            try:
                snap[os.path.relpath(full, root)] = entry_of(full)
            except OSError as e:
                snap[os.path.relpath(full, root)] = ("error", str(e))
    return snap


def under(rel, prefix):
    prefix = os.path.normpath(prefix)
    return rel == prefix or rel.startswith(prefix + os.sep)


def diff_snapshots(before, after, ignore=()):
    changes = []
    for rel in sorted(set(before) | set(after)):
        if any(under(rel, i) for i in ignore):
            continue
        a, b = before.get(rel), after.get(rel)
        if a == b:
            continue
        if a is None:
            changes.append("created %s" % rel)
        elif b is None:
            changes.append("removed %s" % rel)
        else:
            changes.append("changed %s (%s -> %s)" % (rel, a[0], b[0]))
    return changes


def temporaries(root):
    found = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for name in dirnames + filenames:
            if any(t in name for t in TEMP_PATTERNS):
                found.append(os.path.relpath(os.path.join(dirpath, name), root))
    return sorted(found)


def listing(path):
    try:
        return set(os.listdir(path))
    except OSError:
        return set()


# --------------------------------------------------------------------------------------- context

class Ctx:
    """One case's sandbox, and helpers to build and mutate its inputs."""

    def __init__(self, sandbox):
        self.sb = sandbox
        self.home = os.path.join(sandbox, "home")
        os.makedirs(self.home)
        self.valid = os.path.join(ARGS.source_dir, "tests", "data", "walks", "valid_small")
        self.plaza = os.path.join(ARGS.source_dir, "datasets", "plaza1")

    def p(self, *rel):
        return os.path.join(self.sb, *rel)

    def vars(self):
        return {"sb": self.sb, "home": self.home, "valid": self.valid, "plaza": self.plaza}

    # -- building inputs
    def copy_walk(self, dst="w", src="valid_small"):
        source = self.valid if src == "valid_small" else self.plaza if src == "plaza1" else src
        shutil.copytree(source, self.p(dst), symlinks=True)
        return self.p(dst)

    def write(self, rel, data):
        path = self.p(rel)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        if os.path.lexists(path) and not os.path.isfile(path):
            self.remove(rel)
        with open(path, "wb") as f:
            f.write(data if isinstance(data, bytes) else data.encode("utf-8"))
        return path

    def read(self, rel):
        with open(self.p(rel), "r", encoding="utf-8", newline="") as f:
            return f.read()

    def remove(self, rel):
        path = self.p(rel)
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path)
        elif os.path.lexists(path):
            os.unlink(path)

    def replace(self, rel, old, new, count=1):
        text = self.read(rel)
        if old not in text:
            raise SetupError("%s: %r not found" % (rel, old))
        self.write(rel, text.replace(old, new, count))

    def set_line(self, rel, lineno, text):
        """Replaces 1-based line `lineno` of a text file."""
        lines = self.read(rel).split("\n")
        lines[lineno - 1] = text
        self.write(rel, "\n".join(lines))

    def append(self, rel, text):
        with open(self.p(rel), "a", encoding="utf-8") as f:
            f.write(text)

    def mkdir(self, rel, files=None):
        os.makedirs(self.p(rel), exist_ok=True)
        for name, content in (files or {}).items():
            self.write(os.path.join(rel, name), content)
        return self.p(rel)

    def fifo(self, rel):
        self.remove(rel)
        os.mkfifo(self.p(rel))

    def socket(self, rel):
        self.remove(rel)
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            s.bind(self.p(rel))
        finally:
            s.close()

    def symlink(self, target, rel):
        self.remove(rel)
        os.symlink(target, self.p(rel))

    def loop(self, rel):
        """rel -> rel.loop -> rel: a symlink loop."""
        self.remove(rel)
        os.symlink(os.path.basename(rel) + ".loop", self.p(rel))
        os.symlink(os.path.basename(rel), self.p(rel + ".loop"))

    def mark(self, rel):
        """Makes sure a previous output folder carries the marker (older binaries wrote none)."""
        marker = self.p(rel, MARKER)
        if not os.path.lexists(marker):
            with open(marker, "w"):
                pass

    def cli(self, *argv, cwd=".", expect=0, timeout=60.0):
        """Runs the CLI during setup (e.g. a previous output); fails the setup on a bad exit."""
        r = run_cli(list(argv), self.p(cwd), self.home, timeout)
        if expect is not None and r.rc != expect:
            raise SetupError("setup: walkgraph %s -> exit %s: %s" %
                             (" ".join(argv), describe_rc(r.rc), r.stderr[:300]))
        return r


# --------------------------------------------------------------------------------------- cases

@dataclasses.dataclass
class Case:
    name: str
    cls: str
    argv: Sequence[str]
    setup: Optional[Callable[[Ctx], None]] = None
    rc: Union[int, Tuple[int, ...]] = 1
    err: Optional[str] = None        # regex that must match stderr (re.M)
    not_err: Optional[str] = None    # regex that must not match stderr
    out: Optional[str] = None        # intended output, relative to the sandbox
    out_kind: Optional[str] = None   # compare | walk | study | tum: checked on success
    gone: Sequence[str] = ()         # paths (rel. to sandbox) that must not exist afterwards
    may_vanish: Sequence[str] = ()   # paths the run may (must) remove, e.g. stale temporaries
    cwd: str = "."
    timeout: float = 60.0
    as_nobody: bool = False          # run as uid 65534 (cases whose target lies outside)
    watch: Sequence[str] = ()        # outside folders whose listing must not change
    check: Optional[Callable[[Ctx, Result], List[str]]] = None
    runner: Optional[Callable[[Ctx], Result]] = None
    ignore_out_always: bool = False
    limit_as: bool = True


CASES: List[Case] = []


def case(name, cls, argv, **kw):
    if any(c.name == name for c in CASES):
        raise ValueError("duplicate case name " + name)
    CASES.append(Case(name, cls, argv, **kw))


def allof(*patterns):
    """One stderr line starting with "walkgraph: " that matches every pattern ("(?i)" at the
    start of a pattern applies to that pattern only)."""
    parts = []
    for p in patterns:
        if p.startswith("(?i)"):
            p = "(?i:%s)" % p[4:]
        parts.append("(?=.*(?:%s))" % p)
    return r"(?m)^walkgraph: " + "".join(parts)


def seq(*fns):
    def run(ctx):
        for f in fns:
            f(ctx)
    return run


def walk(src="valid_small", dst="w"):
    return lambda ctx: ctx.copy_walk(dst, src)


def with_walk(fn, src="valid_small", dst="w"):
    """Copies a valid walk to ./w, then applies `fn(ctx)`."""
    return seq(walk(src, dst), fn)


def no_long_run(ch, n=150):
    return lambda ctx, r: (["stderr echoes a run of %d+ %r (a 1000-char field echoed whole)"
                            % (n, ch)] if ch * n in r.stderr else [])


def no_long_number(ctx, r):
    m = re.search(r"\d{31,}", r.stderr)
    return ["stderr holds a %d-digit number" % len(m.group(0))] if m else []


def both(*checks):
    return lambda ctx, r: [p for c in checks for p in c(ctx, r)]


def quick(limit_s):
    return lambda ctx, r: (["took %.1f s; expected an answer within %g s" % (
        r.elapsed, limit_s * ARGS.time_scale)] if r.elapsed > limit_s * ARGS.time_scale else [])


def exists_check(*rels):
    def check(ctx, r):
        return ["%s missing" % rel for rel in rels if not os.path.lexists(ctx.p(rel))]
    return check


def no_permission_excuse():
    return r"Permission denied|cannot create|Read-only"


# =============================================================================================
# A. Output folders (compare, simulate, study, convert --out DIR).
#    Every output folder carries .walkgraph-output. An existing target is replaced only when it
#    carries the marker (or is an empty directory); else exit 1 naming --force, untouched.
#    --force replaces an unmarked folder. Never replaced, even with --force: the input walk, a
#    folder containing it, ".", "..", "/", $HOME, an ancestor of the cwd. "dir/" is "dir".
# =============================================================================================

CMP = ["compare", "w", "--estimators", "pdr-only", "--out"]
SIM = ["simulate", "--scenario", "linear-gaussian", "--seed", "1", "--out"]
STUDY = ["study", "m.yaml", "--out"]
CONV = ["convert", "pyshoe", "src.csv", "--out"]

STUDY_MANIFEST = """name: tiny
estimators: [odometry-dr]
pcrb: false
sweeps:
  - name: s
    scenario: linear-gaussian
    overrides: {duration_s: 10}
    scenario_override: range_sigma_m
    values: [0.2, 0.4]
"""


def pyshoe_csv(n=50):
    rows = ["t_s,ax_mps2,ay_mps2,az_mps2,gx_radps,gy_radps,gz_radps,gt_x_m,gt_y_m,gt_z_m,zv_vicon"]
    for i in range(n):
        rows.append("%.2f,0.1,0.0,-9.8,0.0,0.0,0.01,%.3f,0,0.1,%d" % (i * 0.01, i * 0.01,
                                                                    1 if i % 10 < 5 else 0))
    return "\n".join(rows) + "\n"


def inputs_for(kind):
    """Setup of the inputs each writing command needs."""
    if kind == "compare":
        return walk()
    if kind == "study":
        return lambda ctx: ctx.write("m.yaml", STUDY_MANIFEST)
    if kind == "convert":
        return lambda ctx: ctx.write("src.csv", pyshoe_csv())
    return lambda ctx: None


WRITERS = {  # command kind -> (argv prefix, output kind)
    "compare": (CMP, "compare"),
    "simulate": (SIM, "walk"),
    "study": (STUDY, "study"),
    "convert": (CONV, "walk"),
}


def unmarked_dir(rel="out"):
    return lambda ctx: ctx.mkdir(rel, {"precious.txt": "user data\n", "imu.csv": "t_s\n",
                                       "results.json": "{}\n", "sub/keep.txt": "x\n"})


def previous_output(kind, rel="out", junk=True):
    """A previous, marked output of the same command (plus a junk file the replacement drops)."""
    def run(ctx):
        prefix, _ = WRITERS[kind]
        ctx.cli(*(prefix + [rel]))
        ctx.mark(rel)
        if junk:
            ctx.write(os.path.join(rel, "old-junk.txt"), "from the previous output\n")
    return run


for kind, (prefix, okind) in WRITERS.items():
    inp = inputs_for(kind)
    case("out-%s-new" % kind, "output-folders", prefix + ["out"], setup=inp, rc=0, out="out",
         out_kind=okind)
    case("out-%s-unmarked-refused" % kind, "output-folders", prefix + ["out"],
         setup=seq(inp, unmarked_dir()), rc=1, err=allof(r"--force"))
    case("out-%s-unmarked-force" % kind, "output-folders", prefix + ["out", "--force"],
         setup=seq(inp, unmarked_dir()), rc=0, out="out", out_kind=okind,
         gone=["out/precious.txt", "out/sub"])
    case("out-%s-marked-replaced" % kind, "output-folders", prefix + ["out"],
         setup=seq(inp, previous_output(kind)), rc=0, out="out", out_kind=okind,
         gone=["out/old-junk.txt"])
    case("out-%s-empty-dir" % kind, "output-folders", prefix + ["out"],
         setup=seq(inp, lambda ctx: ctx.mkdir("out")), rc=0, out="out", out_kind=okind)
    case("out-%s-home-force" % kind, "output-folders", prefix + ["{home}", "--force"],
         setup=seq(inp, lambda ctx: ctx.write("home/.profile", "# mine\n")), rc=1,
         err=r"(?m)^walkgraph: ", not_err=no_permission_excuse())

case("out-compare-rerun-twice", "output-folders", CMP + ["out"],
     setup=seq(walk(), lambda ctx: ctx.cli(*(CMP + ["out"]))), rc=0, out="out",
     out_kind="compare")
case("out-simulate-rerun-twice", "output-folders", SIM + ["out"],
     setup=lambda ctx: ctx.cli(*(SIM + ["out"])), rc=0, out="out", out_kind="walk")
case("out-compare-trailing-slash-marked", "output-folders", CMP + ["out/"],
     setup=seq(walk(), previous_output("compare")), rc=0, out="out", out_kind="compare",
     gone=["out/old-junk.txt"])
case("out-compare-trailing-slash-unmarked", "output-folders", CMP + ["out/"],
     setup=seq(walk(), unmarked_dir()), rc=1, err=allof(r"--force"))
case("out-simulate-trailing-slash-unmarked", "output-folders", SIM + ["out//"],
     setup=unmarked_dir(), rc=1, err=allof(r"--force"))
case("out-compare-regular-file", "output-folders", CMP + ["out"],
     setup=seq(walk(), lambda ctx: ctx.write("out", "a file, not a folder\n")), rc=1,
     err=allof(r"out"))
case("out-compare-symlink-to-unmarked", "output-folders", CMP + ["out"],
     setup=seq(walk(), unmarked_dir("real"), lambda ctx: ctx.symlink("real", "out")), rc=1,
     err=r"(?m)^walkgraph: ")
case("out-compare-parent-is-file", "output-folders", CMP + ["f.txt/out"],
     setup=seq(walk(), lambda ctx: ctx.write("f.txt", "x\n")), rc=1, err=allof(r"f\.txt"))
case("out-compare-name-too-long", "output-folders", CMP + ["d" * 300],
     setup=walk(), rc=1, err=r"(?m)^walkgraph: ")
case("out-compare-empty-path", "output-folders", CMP + [""], setup=walk(), rc=1,
     err=r"(?m)^walkgraph: ")

# Never replaced, even with --force.
case("never-compare-walk-itself", "never-replaced", CMP + ["w", "--force"], setup=walk(), rc=1,
     err=r"(?m)^walkgraph: ", not_err=no_permission_excuse())
case("never-compare-walk-trailing-slash", "never-replaced", CMP + ["w/", "--force"],
     setup=walk(), rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-walk-dot-path", "never-replaced", CMP + ["./w/.", "--force"],
     setup=walk(), rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-marked-walk-itself", "never-replaced",
     ["compare", "w", "--estimators", "odometry-dr", "--out", "w"],
     setup=lambda ctx: ctx.cli(*(SIM + ["w"])), rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-dot-containing-walk", "never-replaced",
     ["compare", "w", "--estimators", "pdr-only", "--out", ".", "--force"],
     setup=seq(lambda ctx: ctx.copy_walk("work/w"),
               lambda ctx: ctx.write("work/notes.txt", "mine\n")),
     cwd="work", rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-absolute-parent-of-walk", "never-replaced",
     ["compare", "data/w", "--estimators", "pdr-only", "--out", "{sb}/work/data", "--force"],
     setup=lambda ctx: ctx.copy_walk("work/data/w"), cwd="work", rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-dotdot", "never-replaced",
     ["compare", "../../w", "--estimators", "pdr-only", "--out", "..", "--force"],
     setup=seq(walk(), lambda ctx: ctx.mkdir("a/b", {"keep.txt": "x\n"})), cwd="a/b", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-compare-sub-dotdot", "never-replaced",
     ["compare", "../w", "--estimators", "pdr-only", "--out", "sub/..", "--force"],
     setup=seq(walk(), lambda ctx: ctx.mkdir("a/sub")), cwd="a", rc=1, err=r"(?m)^walkgraph: ")
case("never-compare-ancestor-of-cwd", "never-replaced",
     ["compare", "{sb}/w", "--estimators", "pdr-only", "--out", "{sb}/a", "--force"],
     setup=seq(walk(), lambda ctx: ctx.mkdir("a/b/c")), cwd="a/b/c", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-simulate-dot", "never-replaced", SIM + [".", "--force"],
     setup=lambda ctx: ctx.mkdir("work", {"mine.txt": "x\n"}), cwd="work", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-simulate-dotdot", "never-replaced", SIM + ["..", "--force"],
     setup=lambda ctx: ctx.mkdir("a/b", {"mine.txt": "x\n"}), cwd="a/b", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-study-dotdot", "never-replaced", ["study", "../m.yaml", "--out", "..", "--force"],
     setup=seq(lambda ctx: ctx.write("a/m.yaml", STUDY_MANIFEST), lambda ctx: ctx.mkdir("a/b")),
     cwd="a/b", rc=1, err=r"(?m)^walkgraph: ")
case("never-convert-dot", "never-replaced", ["convert", "pyshoe", "src.csv", "--out", ".",
                                               "--force"],
     setup=lambda ctx: ctx.write("work/src.csv", pyshoe_csv()), cwd="work", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-simulate-marked-home", "never-replaced", SIM + ["{home}"],
     setup=lambda ctx: ctx.write("home/" + MARKER, ""), rc=1, err=r"(?m)^walkgraph: ")
case("never-simulate-marked-dot", "never-replaced", SIM + ["."],
     setup=lambda ctx: ctx.mkdir("work", {MARKER: "", "mine.txt": "x\n"}), cwd="work", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-compare-marked-ancestor", "never-replaced",
     ["compare", "{sb}/w", "--estimators", "pdr-only", "--out", "{sb}/a"],
     setup=seq(walk(), lambda ctx: ctx.mkdir("a/b"), lambda ctx: ctx.write("a/" + MARKER, "")),
     cwd="a/b", rc=1,
     err=r"(?m)^walkgraph: ")
case("never-simulate-root", "never-replaced", SIM + ["/", "--force"], as_nobody=True,
     watch=["/"], rc=1, err=r"(?m)^walkgraph: ", not_err=no_permission_excuse())
case("never-compare-root", "never-replaced",
     ["compare", "{sb}/w", "--estimators", "pdr-only", "--out", "/", "--force"], setup=walk(),
     as_nobody=True, watch=["/"], rc=1, err=r"(?m)^walkgraph: ", not_err=no_permission_excuse())


# =============================================================================================
# B. smooth --out FILE: only a new path or an existing regular file is written.
# =============================================================================================

SMOOTH = ["smooth", "w", "--estimator", "rss-only", "--out"]

case("smooth-new-file", "smooth-out", SMOOTH + ["t.tum"], setup=walk(), rc=0, out="t.tum",
     out_kind="tum")
case("smooth-existing-regular-file", "smooth-out", SMOOTH + ["t.tum"],
     setup=seq(walk(), lambda ctx: ctx.write("t.tum", "old\n")), rc=0, out="t.tum",
     out_kind="tum")
case("smooth-out-directory", "smooth-out", SMOOTH + ["dir.tum"],
     setup=seq(walk(), lambda ctx: ctx.mkdir("dir.tum", {"x": "1\n"})), rc=1,
     err=allof(r"dir\.tum"))
case("smooth-out-fifo", "smooth-out", SMOOTH + ["fifo.tum"],
     setup=seq(walk(), lambda ctx: ctx.fifo("fifo.tum")), rc=1, err=allof(r"fifo\.tum"),
     timeout=15)
case("smooth-out-socket", "smooth-out", SMOOTH + ["sock.tum"],
     setup=seq(walk(), lambda ctx: ctx.socket("sock.tum")), rc=1, err=allof(r"sock\.tum"))
case("smooth-out-symlink-dev-full", "smooth-out", SMOOTH + ["full.tum"],
     setup=seq(walk(), lambda ctx: ctx.symlink("/dev/full", "full.tum")), rc=1,
     err=allof(r"full\.tum"))
case("smooth-out-symlink-dev-null", "smooth-out", SMOOTH + ["null.tum"],
     setup=seq(walk(), lambda ctx: ctx.symlink("/dev/null", "null.tum")), rc=1,
     err=allof(r"null\.tum"))
case("smooth-out-symlink-regular", "smooth-out", SMOOTH + ["link.tum"],
     setup=seq(walk(), lambda ctx: ctx.write("real.tum", "mine\n"),
               lambda ctx: ctx.symlink("real.tum", "link.tum")), rc=1, err=allof(r"link\.tum"))
case("smooth-out-dangling-symlink", "smooth-out", SMOOTH + ["dangling.tum"],
     setup=seq(walk(), lambda ctx: ctx.symlink("nowhere/x.tum", "dangling.tum")), rc=1,
     err=allof(r"dangling\.tum"))
case("smooth-out-symlink-loop", "smooth-out", SMOOTH + ["loop.tum"],
     setup=seq(walk(), lambda ctx: ctx.loop("loop.tum")), rc=1, err=allof(r"loop\.tum"))
case("smooth-out-walk-imu", "smooth-out", SMOOTH + ["w/imu.csv"], setup=walk(), rc=1,
     err=allof(r"imu\.csv"))
# A new file beside the walk's own files replaces nothing: allowed (an existing one is refused).
case("smooth-out-new-file-inside-walk", "smooth-out", SMOOTH + ["w/traj.tum"], setup=walk(),
     rc=0, out="w/traj.tum")
case("smooth-out-walk-folder", "smooth-out", SMOOTH + ["w"], setup=walk(), rc=1,
     err=r"(?m)^walkgraph: ")
case("smooth-out-dev-full-direct", "smooth-out", SMOOTH + ["/dev/full"], setup=walk(),
     as_nobody=True, watch=["/dev"], rc=1, err=allof(r"/dev/full"),
     not_err=no_permission_excuse())
case("smooth-out-dev-null-direct", "smooth-out", SMOOTH + ["/dev/null"], setup=walk(),
     as_nobody=True, watch=["/dev"], rc=1, err=allof(r"/dev/null"),
     not_err=no_permission_excuse())
# Creating the missing parent or refusing are both fine; crashing or leaving temporaries is not.
case("smooth-out-missing-parent", "smooth-out", SMOOTH + ["nodir/t.tum"], setup=walk(),
     rc=(0, 1), err=allof(r"nodir"), out="nodir")


# =============================================================================================
# C. Temporaries: hidden siblings ".<name>.walkgraph-tmp-<pid>"; a stale one from a killed run
#    (pid 999999) is cleaned up by the next run writing that target, never taken as output.
# =============================================================================================

def stale(rel_dir, name, as_file=False):
    def run(ctx):
        p = os.path.join(rel_dir, ".%s.walkgraph-tmp-999999" % name)
        if as_file:
            ctx.write(p, "stale temporary\n")
        else:
            ctx.mkdir(p, {"results.json": "{\"stale\": true}\n", "stale.txt": "x\n"})
    return run


case("stale-tmp-compare-new-target", "temporaries", CMP + ["out"],
     setup=seq(walk(), stale(".", "out")), rc=0, out="out", out_kind="compare",
     may_vanish=[".out.walkgraph-tmp-999999"], gone=["out/stale.txt"])
case("stale-tmp-compare-marked-target", "temporaries", CMP + ["out"],
     setup=seq(walk(), previous_output("compare"), stale(".", "out")), rc=0, out="out",
     out_kind="compare", may_vanish=[".out.walkgraph-tmp-999999"],
     gone=["out/stale.txt", "out/old-junk.txt"])
case("stale-tmp-simulate", "temporaries", SIM + ["out"], setup=stale(".", "out"), rc=0,
     out="out", out_kind="walk", may_vanish=[".out.walkgraph-tmp-999999"],
     gone=["out/stale.txt"])
case("stale-tmp-study", "temporaries", STUDY + ["out"],
     setup=seq(inputs_for("study"), stale(".", "out")), rc=0, out="out", out_kind="study",
     may_vanish=[".out.walkgraph-tmp-999999"])
case("stale-tmp-smooth", "temporaries", SMOOTH + ["t.tum"],
     setup=seq(walk(), stale(".", "t.tum", as_file=True)), rc=0, out="t.tum", out_kind="tum",
     may_vanish=[".t.tum.walkgraph-tmp-999999"])
case("stale-tmp-failed-run-leaves-none", "temporaries",
     ["compare", "w", "--estimators", "no-such-estimator", "--out", "out"],
     setup=seq(walk(), previous_output("compare")), rc=1, err=allof(r"no-such-estimator"))


# =============================================================================================
# D. Signals: SIGTERM/SIGINT during compare (plaza1, all estimators, a few seconds) over a
#    previous marked output: afterwards the target is the old output whole or the new whole,
#    and no temporary remains.
# =============================================================================================

_template_lock = threading.Lock()
_template = {}


def old_output_template():
    """A previous compare output on plaza1 (one estimator), made once per suite run."""
    with _template_lock:
        if "path" in _template:
            return _template["path"]
        base = os.path.join(ARGS.root, "_template")
        os.makedirs(os.path.join(base, "home"), exist_ok=True)
        r = run_cli(["compare", os.path.join(ARGS.source_dir, "datasets", "plaza1"),
                     "--estimators", "odometry-dr", "--out", "old"], base,
                    os.path.join(base, "home"), 120)
        if r.rc != 0:
            raise SetupError("template compare on plaza1 -> exit %s: %s" %
                             (describe_rc(r.rc), r.stderr[:300]))
        marker = os.path.join(base, "old", MARKER)
        if not os.path.lexists(marker):
            open(marker, "w").close()
        _template["path"] = os.path.join(base, "old")
        return _template["path"]


def signal_setup(ctx):
    ctx.copy_walk("w", "plaza1")
    shutil.copytree(old_output_template(), ctx.p("out"), symlinks=True)
    ctx.old_snapshot = snapshot(ctx.p("out"))


def signal_runner(sig, delay, after_temporary=False):
    """Sends `sig` `delay` s after the start, or (after_temporary) `delay` s after the first
    temporary appears in the sandbox: the write phase, where a kill does damage."""
    def run(ctx):
        t0 = time.time()
        p = spawn(["compare", "w", "--out", "out"], ctx.sb, ctx.home, limit_as=False)
        if after_temporary:
            while p.poll() is None and time.time() - t0 < 80:
                names = listing(ctx.sb) | listing(ctx.p("out"))
                if any(t in n for n in names for t in TEMP_PATTERNS):
                    break
                time.sleep(0.001)
        time.sleep(delay)
        if p.poll() is None:
            try:
                os.kill(p.pid, sig)
            except ProcessLookupError:
                pass
        return finish(p, 90, t0)
    return run


def compare_output_problems(path):
    """What is wrong with `path` as a complete compare output folder ([] when complete)."""
    problems = []
    for name in ("results.json", "report.html", "errors.csv", MARKER):
        if not os.path.isfile(os.path.join(path, name)):
            problems.append("%s missing" % name)
    if not os.path.isdir(os.path.join(path, "trajectories")):
        problems.append("trajectories/ missing")
    try:
        with open(os.path.join(path, "results.json"), "rb") as f:
            results = json.loads(f.read())
        for est, v in results.get("estimators", {}).items():
            if isinstance(v, dict) and "error" not in v and not os.path.isfile(
                    os.path.join(path, "trajectories", est + ".tum")):
                problems.append("trajectories/%s.tum missing" % est)
    except (OSError, ValueError, AttributeError) as e:
        problems.append("results.json unreadable: %s" % str(e)[:80])
    return problems


def signal_check(sig):
    def check(ctx, r):
        problems = []
        allowed = {0, 1, 128 + sig, -sig}
        if r.rc not in allowed:
            problems.append("exit %s after %s; expected 0, 1, %d" % (describe_rc(r.rc),
                                                                       signal.Signals(sig).name,
                                                                       128 + sig))
        after = snapshot(ctx.p("out"))
        if after == ctx.old_snapshot:
            return problems  # the old output, whole
        if not after:
            return problems + ["target gone: neither the old nor the new output"]
        new_problems = compare_output_problems(ctx.p("out"))
        if new_problems:
            problems.append("target is neither the old output nor a whole new one: " +
                            ", ".join(new_problems[:4]))
        return problems
    return check


# (delay in s, counted from the start | from the first temporary seen in the sandbox)
SIGNAL_DELAYS = [(0.05, False), (0.3, False), (1.0, False), (2.0, False), (3.0, False),
                 (0.0, True), (0.01, True), (0.05, True), (0.15, True), (0.27, True)]
for i, (delay, after_tmp) in enumerate(SIGNAL_DELAYS):
    sig = signal.SIGTERM if i % 2 == 0 else signal.SIGINT
    case("signal-%s-%s%gs" % (signal.Signals(sig).name.lower(), "write-phase+" if after_tmp
                              else "", delay), "signals",
         ["compare", "w", "--out", "out"], setup=signal_setup,
         runner=signal_runner(sig, delay, after_tmp), rc=(0, 1, 128 + sig, -sig),
         check=signal_check(sig), out="out", ignore_out_always=True, limit_as=False, timeout=90)


# =============================================================================================
# E. Special files where a regular file is expected: exit 1 at once, naming the path and
#    saying a regular file was expected.
# =============================================================================================

VALIDATE = ["validate", "w"]
QUICK = 15.0  # "at once": a FIFO must never be opened for reading and waited on


def regular_file_error(name):
    return allof(re.escape(name), r"(?i)regular file")


case("special-walk-yaml-fifo", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.fifo("w/walk.yaml")), timeout=QUICK,
     err=regular_file_error("walk.yaml"))
case("special-rss-fifo", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.fifo("w/rss.csv")), timeout=QUICK,
     err=regular_file_error("rss.csv"))
case("special-imu-socket", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.socket("w/imu.csv")), timeout=QUICK,
     err=regular_file_error("imu.csv"))
case("special-anchors-directory", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.remove("w/anchors.csv") or ctx.mkdir("w/anchors.csv")),
     timeout=QUICK,
     err=regular_file_error("anchors.csv"))
case("special-truth-dev-null", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.symlink("/dev/null", "w/truth.csv")), timeout=QUICK,
     err=regular_file_error("truth.csv"))
case("special-odometry-dev-zero", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.symlink("/dev/zero", "w/odometry.csv")), timeout=QUICK,
     err=regular_file_error("odometry.csv"))
case("special-walk-yaml-dev-full", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.symlink("/dev/full", "w/walk.yaml")), timeout=QUICK,
     err=regular_file_error("walk.yaml"))
case("special-rss-symlink-loop", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.loop("w/rss.csv")), timeout=QUICK,
     err=allof(r"rss\.csv"))
case("special-imu-dangling-symlink", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.symlink("gone/imu.csv", "w/imu.csv")), timeout=QUICK,
     err=allof(r"imu\.csv"))
case("special-stance-truth-fifo", "special-files", VALIDATE,
     setup=with_walk(lambda ctx: ctx.fifo("w/stance_truth.csv")), timeout=QUICK,
     err=regular_file_error("stance_truth.csv"))
case("special-config-fifo", "special-files",
     ["smooth", "w", "--estimator", "rss-only", "--config", "c.yaml", "--out", "t.tum"],
     setup=with_walk(lambda ctx: ctx.fifo("c.yaml")), timeout=QUICK,
     err=regular_file_error("c.yaml"))
case("special-config-socket", "special-files",
     ["compare", "w", "--estimators", "pdr-only", "--config", "c.yaml", "--out", "out"],
     setup=with_walk(lambda ctx: ctx.socket("c.yaml")), timeout=QUICK,
     err=regular_file_error("c.yaml"))
case("special-config-dev-zero", "special-files",
     ["simulate", "--scenario", "linear-gaussian", "--seed", "1", "--config", "c.yaml", "--out",
      "out"], setup=lambda ctx: ctx.symlink("/dev/zero", "c.yaml"), timeout=QUICK,
     err=regular_file_error("c.yaml"))
case("special-config-symlink-loop", "special-files",
     ["simulate", "--scenario", "linear-gaussian", "--seed", "1", "--config", "c.yaml", "--out",
      "out"], setup=lambda ctx: ctx.loop("c.yaml"), timeout=QUICK, err=allof(r"c\.yaml"))
case("special-manifest-fifo", "special-files", ["study", "m.yaml", "--out", "out"],
     setup=lambda ctx: ctx.fifo("m.yaml"), timeout=QUICK, err=regular_file_error("m.yaml"))
case("special-scenario-config-fifo", "special-files",
     ["compare", "--scenario", "linear-gaussian", "--scenario-config", "s.yaml", "--estimators",
      "odometry-dr", "--out", "out"], setup=lambda ctx: ctx.fifo("s.yaml"), timeout=QUICK,
     err=regular_file_error("s.yaml"))
case("special-convert-source-fifo", "special-files", ["convert", "pyshoe", "src.csv", "--out",
                                                        "out"],
     setup=lambda ctx: ctx.fifo("src.csv"), timeout=QUICK, err=regular_file_error("src.csv"))


# =============================================================================================
# F. YAML: directories, duplicate keys, second documents, typos, lists, syntax errors.
# =============================================================================================

SMOOTH_CFG = ["smooth", "w", "--estimator", "rss-only", "--config", "c.yaml", "--out", "t.tum"]
CMP_CFG = ["compare", "w", "--estimators", "pdr-only", "--config", "c.yaml", "--out", "out"]
SIM_CFG = ["simulate", "--scenario", "tarrio-circle", "--seed", "1", "--config", "c.yaml",
           "--out", "out"]
SIM_LG_CFG = ["simulate", "--scenario", "linear-gaussian", "--seed", "1", "--config", "c.yaml",
              "--out", "out"]
DUP = r"(?i)duplicate|repeated|twice|more than once|again"

case("yaml-smooth-config-directory", "yaml", SMOOTH_CFG,
     setup=with_walk(lambda ctx: ctx.mkdir("c.yaml", {"x.yaml": "a: 1\n"})),
     err=allof(r"c\.yaml"))
case("yaml-compare-config-directory", "yaml", CMP_CFG,
     setup=with_walk(lambda ctx: ctx.mkdir("c.yaml")), err=allof(r"c\.yaml"))
case("yaml-simulate-config-directory", "yaml", SIM_LG_CFG,
     setup=lambda ctx: ctx.mkdir("c.yaml"), err=allof(r"c\.yaml"))
case("yaml-walk-yaml-directory", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.remove("w/walk.yaml") or ctx.mkdir("w/walk.yaml")),
     err=allof(r"walk\.yaml"))
case("yaml-walk-duplicate-top-key", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "name: valid_small\n",
                                             "name: valid_small\nname: other\n")),
     err=allof(r"walk\.yaml:[23]:", DUP, r"\bname\b"))
case("yaml-walk-duplicate-nested-key", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "  eta: 2.5\n",
                                             "  eta: 2.5\n  eta: 4.0\n")),
     err=allof(r"walk\.yaml:1[23]:", DUP, r"\beta\b"))
case("yaml-walk-duplicate-section", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.append("w/walk.yaml", "radio:\n  kind: none\n")),
     err=allof(r"walk\.yaml:\d+:", DUP, r"\bradio\b"))
case("yaml-smooth-config-duplicate-key", "yaml", SMOOTH_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "sigma_p_m: 1.0\nsigma_p_m: 2.0\n")),
     err=allof(r"c\.yaml:[12]:", DUP, r"sigma_p_m"))
case("yaml-compare-config-duplicate-estimator", "yaml", CMP_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "pdr-only: {}\npdr-only: {start: "
                                                     "first-fix}\n")),
     err=allof(r"c\.yaml:[12]:", DUP, r"pdr-only"))
case("yaml-simulate-config-duplicate-key", "yaml", SIM_LG_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "duration_s: 10\nduration_s: 20\n"),
     err=allof(r"c\.yaml:[12]:", DUP, r"duration_s"))
# A lone ',' sends yaml-cpp 0.7's LoadAll into an endless loop (found by the fuzzer).
case("yaml-walk-lone-comma", "yaml", VALIDATE, timeout=15,
     setup=with_walk(lambda ctx: ctx.write("w/walk.yaml", ",")),
     err=allof(r"walk\.yaml:1: "))
case("yaml-config-lone-comma", "yaml", SIM_LG_CFG, timeout=15,
     setup=lambda ctx: ctx.write("c.yaml", ",,\n"), err=allof(r"c\.yaml:1: "))
case("yaml-walk-second-document", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.append("w/walk.yaml", "---\nname: second\n")),
     err=allof(r"walk\.yaml", r"(?i)document"))
case("yaml-config-second-document", "yaml", SIM_LG_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "duration_s: 10\n---\nduration_s: 20\n"),
     err=allof(r"c\.yaml", r"(?i)document"))
case("yaml-compare-config-typo-estimator", "yaml", CMP_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "tarrio-kff:\n  sigma_p_m: 2.0\n")),
     err=allof(r"tarrio-kff"))
case("yaml-compare-config-list", "yaml", CMP_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "- pdr-only\n- rss-only\n")),
     err=allof(r"c\.yaml", r"(?i)map"))
case("yaml-smooth-config-list", "yaml", SMOOTH_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "- sigma_p_m\n- 2\n")),
     err=allof(r"c\.yaml", r"(?i)map"))
case("yaml-simulate-config-scalar", "yaml", SIM_LG_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "just a sentence\n"), err=allof(r"c\.yaml"))
case("yaml-walk-syntax-error", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "name: valid_small",
                                             "name: [valid_small")),
     err=allof(r"walk\.yaml:\d+: "))
case("yaml-config-syntax-error", "yaml", CMP_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", "pdr-only: {start: first-fix\n")),
     err=allof(r"c\.yaml:\d+: "))
case("yaml-config-bad-indent", "yaml", SIM_LG_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "duration_s: 10\n  range_every: 2\n bad: [\n"),
     err=allof(r"c\.yaml:\d+: "))
case("yaml-walk-empty-file", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/walk.yaml", "")), err=allof(r"walk\.yaml"))
case("yaml-walk-deep-nesting", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/walk.yaml", "format_version: 1\nname: " +
                                           "[" * 100000 + "]" * 100000 + "\n")),
     err=allof(r"walk\.yaml"))
case("yaml-config-deep-nesting", "yaml", SIM_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "laps: " + "{a: " * 50000 + "1" + "}" * 50000 + "\n"),
     err=allof(r"c\.yaml|laps"))


def billion_laughs(ctx):
    lines = ["a0: &a0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, 25):
        lines.append("a%d: &a%d [%s]" % (i, i, ", ".join(["*a%d" % (i - 1)] * 10)))
    lines.append("laps: *a24")
    ctx.write("c.yaml", "\n".join(lines) + "\n")


case("yaml-config-billion-laughs", "yaml", SIM_CFG, setup=billion_laughs, timeout=30,
     err=r"(?m)^walkgraph: ")
case("yaml-walk-name-not-string", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "name: valid_small",
                                             "name: {a: 1}")),
     err=allof(r"walk\.yaml", r"\bname\b"))
case("yaml-walk-format-version-huge", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "format_version: 1",
                                             "format_version: " + "9" * 40)),
     err=allof(r"walk\.yaml", r"format_version"), check=no_long_number)
case("yaml-walk-nan-eta", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "eta: 2.5", "eta: .nan")),
     err=allof(r"walk\.yaml", r"\beta\b"))
case("yaml-walk-inf-initial-x", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "x_m: 0", "x_m: .inf")),
     err=allof(r"walk\.yaml", r"x_m"))
case("yaml-walk-crlf-accepted", "yaml", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/walk.yaml", ctx.read("w/walk.yaml")
                                           .replace("\n", "\r\n"))), rc=0)


# =============================================================================================
# G. walk.yaml contradictions.
# =============================================================================================

case("contradiction-radio-none-with-rss", "walk-yaml-contradictions", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "kind: rss", "kind: none")),
     err=allof(r"rss\.csv|walk\.yaml", r"\bnone\b|radio"))
case("contradiction-radio-none-with-range", "walk-yaml-contradictions", VALIDATE,
     setup=with_walk(seq(lambda ctx: ctx.replace("w/walk.yaml", "kind: rss", "kind: none"),
                         lambda ctx: ctx.remove("w/rss.csv"),
                         lambda ctx: ctx.write("w/range.csv", "t_s,anchor_id,range_m\n"
                                               "0.0,1,2.0\n1.0,2,8.5\n"))),
     err=allof(r"range\.csv|walk\.yaml", r"\bnone\b|radio"))
case("contradiction-imu-none-with-imu", "walk-yaml-contradictions", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "imu_placement: waist",
                                             "imu_placement: none")),
     err=allof(r"imu\.csv|walk\.yaml", r"imu_placement|\bnone\b"))
case("contradiction-truth-none-with-truth", "walk-yaml-contradictions", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "truth: continuous",
                                             "truth: none")),
     err=allof(r"truth"))
case("contradiction-imu-none-compare", "walk-yaml-contradictions", CMP + ["out"],
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "imu_placement: waist",
                                             "imu_placement: none")),
     err=allof(r"imu\.csv|walk\.yaml", r"imu_placement|\bnone\b"))


# =============================================================================================
# H. CSV content: hex numbers, nanosecond timestamps, header-only streams, huge fields/lines,
#    NUL bytes, denormals, NaN/Inf, wrong headers, truncation, BOM/CRLF.
# =============================================================================================

def csv_line(rel, lineno, text):
    return with_walk(lambda ctx: ctx.set_line("w/" + rel, lineno, text))


case("csv-hex-anchor-id", "csv", VALIDATE, setup=csv_line("anchors.csv", 3, "0x2,10,0,2"),
     err=allof(r"anchors\.csv:3: ", r"\bid\b"))
case("csv-hex-rss-anchor-id", "csv", VALIDATE, setup=csv_line("rss.csv", 3, "0.00,0x2,-85.5"),
     err=allof(r"rss\.csv:3: ", r"anchor_id"))
case("csv-hex-float-imu-time", "csv", VALIDATE,
     setup=csv_line("imu.csv", 3, "0x1p-5,0.2,0.0,9.70,0.0,0.0,0.01"),
     err=allof(r"imu\.csv:3: ", r"t_s"))
case("csv-hex-rss-value", "csv", VALIDATE, setup=csv_line("rss.csv", 3, "0.00,2,-0x55.8p0"),
     err=allof(r"rss\.csv:3: ", r"\brss\b"))
case("csv-hex-truth-x", "csv", VALIDATE, setup=csv_line("truth.csv", 3, "0.5,0x1.6p-1,0"),
     err=allof(r"truth\.csv:3: ", r"x_m"))
case("csv-hex-odometry-dist", "csv", VALIDATE, setup=csv_line("odometry.csv", 2, "0.5,0X.Bp0,0.0"),
     err=allof(r"odometry\.csv:2: ", r"dist_m"))


def ns_times(rel):
    def run(ctx):
        lines = ctx.read("w/" + rel).rstrip("\n").split("\n")
        out = [lines[0]]
        for i, line in enumerate(lines[1:]):
            rest = line.split(",", 1)[1]
            out.append("%d,%s" % (1700000000000000000 + i * 20000000, rest))
        ctx.write("w/" + rel, "\n".join(out) + "\n")
    return with_walk(run)


case("csv-nanoseconds-imu", "csv", VALIDATE, setup=ns_times("imu.csv"),
     err=allof(r"imu\.csv:\d+: ", r"(?i)nanosecond"))
case("csv-nanoseconds-odometry", "csv", VALIDATE, setup=ns_times("odometry.csv"),
     err=allof(r"odometry\.csv:\d+: ", r"(?i)nanosecond"))


def ns_everything(ctx):
    for rel in ("imu.csv", "odometry.csv", "truth.csv"):
        lines = ctx.read("w/" + rel).rstrip("\n").split("\n")
        out = [lines[0]] + ["%d,%s" % (1700000000000000000 + i * 500000000, l.split(",", 1)[1])
                            for i, l in enumerate(lines[1:])]
        ctx.write("w/" + rel, "\n".join(out) + "\n")
    ctx.write("w/rss.csv", "t_s,anchor_id,rss\n1.7e18,1,-62.0\n1.7e18,2,-85.5\n")


case("csv-nanoseconds-all-streams", "csv", VALIDATE, setup=with_walk(ns_everything),
     err=allof(r"\.csv:\d+: ", r"(?i)nanosecond"))
case("csv-header-only-stance-truth", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/stance_truth.csv", "t_s,stance\n")),
     err=allof(r"stance_truth\.csv:\d+: ", r"(?i)no samples|at least one|no rows|no data"))
case("csv-header-only-rss", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/rss.csv", "t_s,anchor_id,rss\n")),
     err=allof(r"rss\.csv:\d+: "))
case("csv-empty-odometry", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/odometry.csv", "")),
     err=allof(r"odometry\.csv:1: "))
case("csv-field-1mb", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/rss.csv", "t_s,anchor_id,rss\n0.00,1,-62.0\n"
                                           "0.00,2,-8" + "5" * (1 << 20) + "\n")),
     err=allof(r"rss\.csv:3: "), check=no_long_run("5"))
case("csv-line-64mb-no-newline", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/rss.csv", b"t_s,anchor_id,rss\n0.00,1,-6" +
                                           b"2" * (64 << 20))),
     err=allof(r"rss\.csv:2: "), check=no_long_run("2"), timeout=60)
case("csv-10mb-nul-bytes", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/imu.csv", b"\0" * (10 << 20))),
     err=allof(r"imu\.csv:1: "), check=no_long_run("\0", 120))
case("csv-nul-inside-number", "csv", VALIDATE,
     setup=csv_line("rss.csv", 3, "0.00,2,-85\0.5"), err=allof(r"rss\.csv:3: "))
case("csv-utf16-file", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/anchors.csv", ctx.read("w/anchors.csv")
                                           .encode("utf-16"))),
     err=allof(r"anchors\.csv:1: "))
case("csv-denormal-imu-accepted", "csv", VALIDATE,
     setup=csv_line("imu.csv", 3, "0.02,0.2,0.0,9.70,1e-320,0.0,0.01"), rc=0)
case("csv-denormal-odometry-accepted", "csv", VALIDATE,
     setup=csv_line("odometry.csv", 3, "1.0,0.7,-4.9e-324"), rc=0)
case("csv-overflow-value", "csv", VALIDATE, setup=csv_line("rss.csv", 3, "0.00,2,-1e400"),
     err=allof(r"rss\.csv:3: "))
case("csv-nan-truth", "csv", VALIDATE, setup=csv_line("truth.csv", 4, "1.0,nan,0"),
     err=allof(r"truth\.csv:4: ", r"x_m"))
case("csv-inf-imu", "csv", VALIDATE,
     setup=csv_line("imu.csv", 2, "0.00,Infinity,0.0,9.81,0.0,0.0,0.01"),
     err=allof(r"imu\.csv:2: ", r"\bax\b"))
case("csv-negative-nan-odometry", "csv", VALIDATE, setup=csv_line("odometry.csv", 2,
                                                                   "0.5,-nan,0.0"),
     err=allof(r"odometry\.csv:2: "))
case("csv-wrong-header", "csv", VALIDATE,
     setup=csv_line("rss.csv", 1, "time,anchor,rssi"), err=allof(r"rss\.csv:1: ", r"(?i)header"))
case("csv-header-case", "csv", VALIDATE,
     setup=csv_line("imu.csv", 1, "T_S,AX,AY,AZ,GX,GY,GZ"), err=allof(r"imu\.csv:1: "))
case("csv-extra-column", "csv", VALIDATE, setup=csv_line("rss.csv", 3, "0.00,2,-85.5,7"),
     err=allof(r"rss\.csv:3: ", r"(?i)column"))
case("csv-decimal-comma", "csv", VALIDATE, setup=csv_line("truth.csv", 3, "0.5,0,7,0"),
     err=allof(r"truth\.csv:3: "))
case("csv-truncated-last-line", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/odometry.csv", ctx.read("w/odometry.csv")
                                           .rstrip("\n")[:-4])),
     err=allof(r"odometry\.csv:5: "))
case("csv-blank-line-inside", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/rss.csv", "0.00,2,-85.5\n",
                                             "0.00,2,-85.5\n\n")),
     err=allof(r"rss\.csv:\d+: "))
case("csv-negative-time", "csv", VALIDATE, setup=csv_line("truth.csv", 2, "-1.0,0,0"),
     err=allof(r"truth\.csv:2: ", r"t_s"))
case("csv-negative-range", "csv", VALIDATE,
     setup=with_walk(seq(lambda ctx: ctx.replace("w/walk.yaml", "kind: rss", "kind: range"),
                         lambda ctx: ctx.remove("w/rss.csv"),
                         lambda ctx: ctx.write("w/range.csv", "t_s,anchor_id,range_m\n"
                                               "0.0,1,2.0\n1.0,2,-3.0\n"))),
     err=allof(r"range\.csv:3: "))
case("csv-absurd-acceleration", "csv", VALIDATE,
     setup=csv_line("imu.csv", 2, "0.00,1e9,0.0,9.81,0.0,0.0,0.01"), err=allof(r"imu\.csv:2: "))
case("csv-anchor-id-over-int", "csv", VALIDATE, setup=csv_line("anchors.csv", 4, "3000000000,0,10,2"),
     err=allof(r"anchors\.csv:4: ", r"\bid\b"))
case("csv-rss-anchor-id-huge", "csv", VALIDATE, setup=csv_line("rss.csv", 2, "0.00,1e10,-62.0"),
     err=allof(r"rss\.csv:2: ", r"anchor_id"))
case("csv-anchor-coordinate-absurd", "csv", VALIDATE,
     setup=csv_line("anchors.csv", 2, "1,1e300,0,2"), err=allof(r"anchors\.csv:2: "))
case("csv-stance-value-2", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/stance_truth.csv", "t_s,stance\n0.0,1\n0.5,2\n")),
     err=allof(r"stance_truth\.csv:3: ", r"stance"))


def bom_crlf(ctx):
    for name in os.listdir(ctx.p("w")):
        if name.endswith(".csv"):
            ctx.write("w/" + name, b"\xef\xbb\xbf" +
                      ctx.read("w/" + name).replace("\n", "\r\n").encode("utf-8"))


case("csv-bom-crlf-accepted", "csv", VALIDATE, setup=with_walk(bom_crlf), rc=0)
case("csv-bom-crlf-compare-accepted", "csv", CMP + ["out"], setup=with_walk(bom_crlf), rc=0,
     out="out", out_kind="compare")
case("csv-no-final-newline-accepted", "csv", VALIDATE,
     setup=with_walk(lambda ctx: ctx.write("w/rss.csv", ctx.read("w/rss.csv").rstrip("\n"))),
     rc=0)


# Non-UTF-8 walk name: validate says UTF-8, or, if accepted, compare must not crash.
def utf8_setup(ctx):
    ctx.copy_walk()
    data = ctx.read("w/walk.yaml").encode("utf-8").replace(b"name: valid_small",
                                                           b"name: bad\xff\xfename")
    ctx.write("w/walk.yaml", data)


def utf8_check(ctx, r):
    if r.rc == 1:
        return [] if re.search(r"(?i)utf-?8", r.stderr) else [
            "validate rejected the name without a message about UTF-8"]
    if r.rc != 0:
        return []  # the generic exit-code check reports it
    c = run_cli(CMP + ["out"], ctx.sb, ctx.home, 60)
    problems = []
    if c.rc not in (0, 1):
        problems.append("validate accepted it; compare then exited %s: %r" %
                        (describe_rc(c.rc), c.stderr[:200]))
    if len(c.stderr) >= MAX_STDERR:
        problems.append("compare stderr %d chars" % len(c.stderr))
    if c.rc == 1 and os.path.lexists(ctx.p("out")):
        problems.append("compare failed but left a partial output folder")
    if c.rc == 0:
        problems += ["compare output: " + p for p in compare_output_problems(ctx.p("out"))]
    return problems


case("utf8-invalid-walk-name", "csv", VALIDATE, setup=utf8_setup, rc=(0, 1), check=utf8_check,
     ignore_out_always=True, out="out")


# =============================================================================================
# H2. Radio maps: --radio-map MAP reads MAP/anchors.csv as strictly as a walk's anchors.csv and
#     refuses a map whose surveyed anchors are not the walk's after a rigid motion; exit 1, the
#     map's file named, no output folder.
# =============================================================================================

RADIO_MAP = ["compare", "w", "--radio-map", "m", "--estimators", "pdr-only", "--out", "o"]


def radio_map(text):
    return with_walk(lambda ctx: ctx.write("m/anchors.csv", text))


case("radio-map-nan-sigma", "radio-map", RADIO_MAP,
     setup=radio_map("id,x_m,y_m,z_m,sigma_m\n1,0,0,2,0\n4,5,5,2,nan\n"),
     err=allof(r"m/anchors\.csv:3: ", r"sigma_m"), gone=["o"])
case("radio-map-negative-sigma", "radio-map", RADIO_MAP,
     setup=radio_map("id,x_m,y_m,z_m,sigma_m\n1,0,0,2,0\n4,5,5,2,-1\n"),
     err=allof(r"m/anchors\.csv:3: ", r"sigma_m"), gone=["o"])
case("radio-map-missing", "radio-map", RADIO_MAP, setup=walk(),
     err=allof(r"m/anchors\.csv"), gone=["o"])
case("radio-map-fifo", "radio-map", RADIO_MAP,
     setup=with_walk(seq(lambda ctx: ctx.mkdir("m"), lambda ctx: ctx.fifo("m/anchors.csv"))),
     timeout=QUICK,
     err=regular_file_error("anchors.csv"), gone=["o"])
case("radio-map-other-building", "radio-map", RADIO_MAP,
     setup=radio_map("id,x_m,y_m,z_m\n1,0,0,2\n2,20,0,2\n3,0,10,2\n"),
     err=allof(r"m/anchors\.csv", r"rms"), gone=["o"])
case("survey-walk-without-truth", "radio-map", ["survey", "w", "--out", "m"],
     setup=with_walk(lambda ctx: ctx.remove("w/truth.csv")), err=allof(r"truth\.csv"),
     gone=["m"])
case("survey-walks-of-two-buildings", "radio-map", ["survey", "w", "w2", "--out", "m"],
     setup=seq(walk(), walk(dst="w2"), lambda ctx: ctx.set_line("w2/anchors.csv", 3, "2,20,0,2")),
     err=allof(r"survey: walk 2 of 2 ", r"rms"), gone=["m"])


# =============================================================================================
# I. Long fields: messages never echo more than ~120 characters of one field.
# =============================================================================================

JUNK = "X" * 1000
case("echo-junk-csv-field", "long-fields", VALIDATE,
     setup=csv_line("rss.csv", 3, "0.00,2," + JUNK), err=allof(r"rss\.csv:3: "),
     check=no_long_run("X"))
case("echo-junk-csv-header", "long-fields", VALIDATE,
     setup=csv_line("rss.csv", 1, "t_s,anchor_id,rss" + JUNK), err=allof(r"rss\.csv:1: "),
     check=no_long_run("X"))
case("echo-junk-yaml-enum", "long-fields", VALIDATE,
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "imu_placement: waist",
                                             "imu_placement: " + JUNK)),
     err=allof(r"walk\.yaml", r"imu_placement"), check=no_long_run("X"))
case("echo-junk-config-key", "long-fields", SMOOTH_CFG,
     setup=with_walk(lambda ctx: ctx.write("c.yaml", JUNK + ": 1\n")), err=allof(r"c\.yaml"),
     check=no_long_run("X"))
case("echo-junk-estimator-id", "long-fields",
     ["compare", "w", "--estimators", "pdr-only," + JUNK, "--out", "out"], setup=walk(),
     err=allof(r"(?i)estimator"), check=no_long_run("X"))
case("echo-junk-scenario-name", "long-fields",
     ["simulate", "--scenario", JUNK, "--seed", "1", "--out", "out"],
     err=allof(r"(?i)scenario"), check=no_long_run("X"))


# =============================================================================================
# J. CLI numbers and ids.
# =============================================================================================

SIM_SEED = ["simulate", "--scenario", "linear-gaussian", "--out", "out", "--seed"]
MC = ["compare", "--scenario", "linear-gaussian", "--estimators", "odometry-dr", "--out", "out"]

case("cli-seed-negative-simulate", "cli-numbers", SIM_SEED + ["-1"], err=allof(r"seed"))
case("cli-seed-negative-compare", "cli-numbers", MC + ["--seed", "-1"], err=allof(r"seed"))
case("cli-seed-2pow64", "cli-numbers", SIM_SEED + ["18446744073709551616"], err=allof(r"seed"))
case("cli-seed-fraction", "cli-numbers", SIM_SEED + ["1.5"], err=allof(r"seed"))
case("cli-seed-huge-pcrb", "cli-numbers",
     ["pcrb", "--scenario", "linear-gaussian", "--seed", "-5"], err=allof(r"seed"))
case("cli-threads-100000-compare", "cli-numbers", MC + ["--threads", "100000"],
     err=allof(r"threads", r"\b\d{1,4}\b"), timeout=60)
case("cli-threads-100000-study", "cli-numbers", STUDY + ["out", "--threads", "100000"],
     setup=inputs_for("study"), err=allof(r"threads", r"\b\d{1,4}\b"), timeout=60)
case("cli-threads-int-overflow", "cli-numbers", MC + ["--threads", "4294967297"],
     err=allof(r"threads"))
case("cli-runs-overflow", "cli-numbers", MC + ["--runs", "99999999999"], err=allof(r"runs"))
case("cli-estimators-only-commas", "cli-numbers",
     ["compare", "w", "--estimators", ",,,", "--out", "out"], setup=walk(),
     err=allof(r"(?i)estimator"), not_err=r"--out is required")
case("cli-estimators-empty-item", "cli-numbers",
     ["compare", "w", "--estimators", "pdr-only,,rss-only", "--out", "out"], setup=walk(),
     err=allof(r"(?i)estimator"))
case("cli-estimator-unknown", "cli-numbers",
     ["compare", "w", "--estimators", "pdr-only,nope-xyz", "--out", "out"], setup=walk(),
     err=allof(r"nope-xyz"))
case("cli-smooth-estimator-unknown", "cli-numbers",
     ["smooth", "w", "--estimator", "nope-xyz", "--out", "t.tum"], setup=walk(),
     err=allof(r"nope-xyz"))
case("cli-score-from-nan", "cli-numbers",
     ["compare", "w", "--estimators", "pdr-only", "--score-from", "nan", "--out", "out"],
     setup=walk(), err=allof(r"score-from|score_from"))
case("cli-unknown-flag-exit-1", "cli-numbers", ["validate", "w", "--frobnicate"], setup=walk(),
     err=r"(?m)^walkgraph: ")
case("cli-verbosity-overflow", "cli-numbers", ["-v", "99999999999999999999", "list"],
     err=allof(r"verbosity|-v"))
case("cli-scenario-unknown", "cli-numbers",
     ["simulate", "--scenario", "no-such-scenario", "--seed", "1", "--out", "out"],
     err=allof(r"no-such-scenario"))


# =============================================================================================
# K. Simulator overrides (simulate --config, compare --scenario-config): absurd values fail
#    quickly with a readable message (no 30+ digit numbers), no crash, no huge memory.
# =============================================================================================

OVERRIDES = [
    ("laps-int-max", "laps: 2147483647", r"laps"),
    ("num-anchors-2e9", "num_anchors: 2000000000", r"num_anchors"),
    ("duration-1e12", "duration_s: 1e12", r"duration_s"),
    ("duration-nan", "duration_s: .nan", r"duration_s"),
    ("speed-inf", "speed_mps: .inf", r"speed_mps"),
    ("imu-rate-1e300", "imu_rate_hz: 1e300", r"imu_rate_hz"),
    ("laps-1e400", "laps: 1e400", r"laps"),
    ("num-anchors-negative", "num_anchors: -5", r"num_anchors"),
    ("eta-nan", "eta: .nan", r"\beta\b"),
    ("sigma-db-huge", "sigma_db: 1e308", r"sigma_db"),
]
for slug, text, key in OVERRIDES:
    case("override-simulate-" + slug, "simulate-overrides", SIM_CFG,
         setup=(lambda t: lambda ctx: ctx.write("c.yaml", t + "\n"))(text), err=allof(key),
         check=both(no_long_number, quick(10)), timeout=30)
for slug, text, key in OVERRIDES[:4]:
    case("override-compare-" + slug, "simulate-overrides",
         ["compare", "--scenario", "tarrio-circle", "--scenario-config", "s.yaml", "--estimators",
          "rss-only", "--out", "out"],
         setup=(lambda t: lambda ctx: ctx.write("s.yaml", t + "\n"))(text), err=allof(key),
         check=both(no_long_number, quick(10)), timeout=30)
case("override-linear-gaussian-duration-1e12", "simulate-overrides", SIM_LG_CFG,
     setup=lambda ctx: ctx.write("c.yaml", "duration_s: 1e12\n"), err=allof(r"duration_s"),
     check=both(no_long_number, quick(10)), timeout=30)
case("override-pcrb-num-anchors-2e9", "simulate-overrides",
     ["pcrb", "--scenario", "tarrio-circle", "--scenario-config", "s.yaml"],
     setup=lambda ctx: ctx.write("s.yaml", "num_anchors: 2000000000\n"),
     err=allof(r"num_anchors"), check=both(no_long_number, quick(10)), timeout=30)


# =============================================================================================
# L. Study manifests: exit 1 with the manifest path in the message.
# =============================================================================================

def manifest(text):
    return lambda ctx: ctx.write("m.yaml", text)


case("study-manifest-directory", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=lambda ctx: ctx.mkdir("m.yaml", {"a.yaml": STUDY_MANIFEST}),
     err=allof(r"m\.yaml", r"(?i)regular file|directory"))
case("study-manifest-duplicate-key", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST.replace("pcrb: false\n", "pcrb: false\npcrb: true\n")),
     err=allof(r"m\.yaml:[34]:", DUP, r"pcrb"))
case("study-manifest-duplicate-sweep-key", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST.replace("    values: [0.2, 0.4]\n",
                                           "    values: [0.2, 0.4]\n    values: [1]\n")),
     err=allof(r"m\.yaml:\d+:", DUP, r"values"))
case("study-manifest-unknown-estimator", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST.replace("[odometry-dr]", "[odometry-dr, tarrio-kff]")),
     err=allof(r"m\.yaml", r"tarrio-kff"))
case("study-manifest-missing-walk", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest("name: w\nestimators: [pdr-only]\npcrb: false\nsweeps:\n  - name: s\n"
                    "    walk: walks/nowhere\n    estimator_option: start\n"
                    "    values: [1]\n"),
     err=allof(r"m\.yaml", r"nowhere"))
case("study-manifest-walk-is-file", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=seq(manifest("name: w\nestimators: [pdr-only]\npcrb: false\nsweeps:\n  - name: s\n"
                        "    walk: f.txt\n    estimator_option: start\n    values: [1]\n"),
               lambda ctx: ctx.write("f.txt", "x\n")),
     err=allof(r"m\.yaml", r"f\.txt"))
case("study-manifest-empty", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(""), err=allof(r"m\.yaml"))
case("study-manifest-list", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest("- name: x\n"), err=allof(r"m\.yaml"))
case("study-manifest-nan-value", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST.replace("[0.2, 0.4]", "[0.2, .nan]")),
     err=allof(r"m\.yaml"))
case("study-manifest-runs-overflow", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST.replace("pcrb: false\n", "pcrb: false\nruns: 2147483648\n")),
     err=allof(r"m\.yaml", r"runs"))
case("study-manifest-second-document", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=manifest(STUDY_MANIFEST + "---\nname: other\n"), err=allof(r"m\.yaml", r"(?i)document"))
case("study-manifest-symlink-loop", "study-manifest", ["study", "m.yaml", "--out", "out"],
     setup=lambda ctx: ctx.loop("m.yaml"), timeout=QUICK, err=allof(r"m\.yaml"))


# --------------------------------------------------------------------------------------- checks

# =============================================================================================
# M. Issue 42: plausibility across streams and of walk.yaml's values and fits, stdout write
#    errors, output names up to NAME_MAX, SIGQUIT, and the writer's lock on shared folders (a
#    second writer of a target, in this or another PID namespace, is refused; a live writer's
#    temporary is never taken for stale).
# =============================================================================================

def dev_full_runner(argv):
    """Runs the CLI with its standard output on /dev/full."""
    def run(ctx):
        t0 = time.time()
        p = subprocess.Popen(["/bin/sh", "-c", 'exec "$0" "$@" > /dev/full', ARGS.cli] + argv,
                             cwd=ctx.sb, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, start_new_session=True,
                             env=dict(os.environ, HOME=ctx.home, LC_ALL="C"))
        return finish(p, 60, t0)
    return run


for argv in (["list"], ["--help"], ["validate", "w"]):
    case("stdout-dev-full-" + argv[0].strip("-"), "plausibility", argv, setup=walk(),
         runner=dev_full_runner(argv), err=allof(r"cannot write the standard output"))


def rising_rss_walk(ctx):
    """A walk whose RSS rises with the distance to its one anchor: the fit's eta is negative."""
    ctx.write("w/walk.yaml", "format_version: 1\nname: rising\nsource: test\nlicence: CC0-1.0\n"
              "imu_placement: none\nframe: enu\ntruth: continuous\n"
              "radio: {kind: rss, units: dbm}\n")
    ctx.write("w/anchors.csv", "id,x_m,y_m,z_m\n1,0,0,0\n")
    ctx.write("w/truth.csv", "t_s,x_m,y_m\n" + "".join(
        "%d,%d,0\n" % (t, t + 1) for t in range(40)))
    ctx.write("w/rss.csv", "t_s,anchor_id,rss\n" + "".join(
        "%d.5,1,%.3f\n" % (t, -90.0 + 25.0 * __import__("math").log10(t + 1.5))
        for t in range(39)))


case("fit-path-loss-absurd-fit-refused", "plausibility", ["fit-path-loss", "w"],
     setup=rising_rss_walk, err=allof(r"fit-path-loss", r"eta -", r"outside \(0, 10\]",
                                      r"not a usable path-loss model"))


def rss_walk(rss_at):
    """rising_rss_walk's walk with the RSS rss_at(distance) (dBm): a constant RSS fits eta 0,
    RSS exactly on a model fits sigma 0 (the issue's absurd fits)."""
    def run(ctx):
        rising_rss_walk(ctx)
        ctx.write("w/rss.csv", "t_s,anchor_id,rss\n" + "".join(
            "%d.5,1,%.6f\n" % (t, rss_at(t + 1.5)) for t in range(39)))
    return run


case("fit-path-loss-eta-0-refused", "plausibility", ["fit-path-loss", "w"],
     setup=rss_walk(lambda d: -70.0),
     err=allof(r"fit-path-loss", r"eta -?[0-9.e+-]+ outside \(0, 10\]",
               r"not a usable path-loss model"))
case("fit-path-loss-sigma-0-refused", "plausibility", ["fit-path-loss", "w"],
     setup=rss_walk(lambda d: -40.0 - 25.0 * __import__("math").log10(d)),
     err=allof(r"fit-path-loss", r"sigma_db [0-9.e+-]+ outside \[0\.001, 50\] dB",
               r"not a usable path-loss model"))
case("waypoint-after-the-walk", "plausibility", ["validate", "w"],
     setup=with_walk(lambda ctx: ctx.set_line("w/waypoints.csv", 3, "1e9,2.1,0.05,0.5")),
     err=allof(r"waypoints\.csv:3", r"outside the walk's time span"))
case("imu-1000-s-from-the-radio", "plausibility", ["validate", "w"],
     setup=with_walk(lambda ctx: ctx.write("w/imu.csv", "\n".join(
         [ctx.read("w/imu.csv").split("\n")[0]] +
         ["%.2f,%s" % (float(l.split(",", 1)[0]) + 1000.0, l.split(",", 1)[1])
          for l in ctx.read("w/imu.csv").strip().split("\n")[1:]]) + "\n")),
     err=allof(r"imu\.csv spans", r"rss\.csv", r"do not overlap"))
case("every-range-zero", "plausibility", ["validate", "w"],
     setup=with_walk(lambda ctx: ctx.write("w/range.csv", "\n".join(
         [l if i == 0 else ",".join(l.split(",")[:2] + ["0"])
          for i, l in enumerate(ctx.read("w/range.csv").strip().split("\n"))]) + "\n"),
         src="plaza1"),
     err=allof(r"range\.csv: every range_m is 0"))
case("rfcode-units-with-dbm-readings", "plausibility", ["validate", "w"],
     setup=with_walk(lambda ctx: ctx.replace("w/walk.yaml", "units: dbm\n  A_dbm: -60",
                                             "units: rfcode\n  A_dbm: 100")),
     err=allof(r"rss\.csv: every reading is negative \(dBm-like\)"))
case("anchors-in-another-frame", "plausibility", ["validate", "w"],
     setup=with_walk(lambda ctx: ctx.write(
         "w/anchors.csv", "id,x_m,y_m,z_m\n1,4800000,0,2\n2,4800010,0,2\n3,4800020,0,2\n")),
     err=allof(r"truth\.csv:2: \(0, 0\) is", r"one frame"))
WALK_YAML_ABSURD = [
    ("eta-1e6", "eta: 2.5", "eta: 1e6", r"radio: eta 1e\+06 outside"),
    ("a-dbm-minus-9.9e6", "A_dbm: -60", "A_dbm: -9.9e6", r"radio: A_dbm -9\.9e\+06 outside"),
    ("sigma-db-tiny", "sigma_db: 5", "sigma_db: 1e-12", r"radio: sigma_db 1e-12 outside"),
    ("heading-in-degrees", "heading_rad: 0", "heading_rad: 180", r"heading_rad 180 outside"),
    ("start-x-1e9", "x_m: 0", "x_m: 1e9", r"initial_pose: x_m 1e\+09 outside"),
    ("start-sigma-tiny", "heading_rad: 0", "heading_rad: 0\n  sigma_xy_m: 1e-12",
     r"sigma_xy_m 1e-12 outside"),
]
for slug, old, new, pattern in WALK_YAML_ABSURD:
    case("walk-yaml-absurd-" + slug, "plausibility", ["validate", "w"],
         setup=with_walk((lambda o, n: lambda ctx: ctx.replace("w/walk.yaml", o, n))(old, new)),
         err=allof(r"walk\.yaml", pattern))

case("compare-runs-2e9-refused", "plausibility",
     ["compare", "--scenario", "tarrio-circle", "--runs", "2000000000", "--out", "out"],
     err=allof(r"runs must be in \[1, 1000000\]"), check=quick(10), timeout=30)
case("study-10001-values-refused", "plausibility", STUDY + ["out"],
     setup=manifest(STUDY_MANIFEST.replace("values: [0.2, 0.4]", "values: [%s]" % ", ".join(
         "%g" % (0.1 + i * 1e-4) for i in range(10001)))),
     err=allof(r"m\.yaml:\d+", r"10001 values, over the cap of 10000"), check=quick(10),
     timeout=30)

LONG_NAME = "n" * 255  # NAME_MAX: the hidden temporary's name must still fit
case("out-name-255-bytes", "plausibility", CMP + [LONG_NAME], setup=walk(), rc=0, out=LONG_NAME,
     out_kind="compare")
case("out-name-256-bytes", "plausibility", CMP + ["n" * 256], setup=walk(),
     err=allof(r"(?i)name too long"))
case("signal-sigquit-write-phase", "signals", ["compare", "w", "--out", "out"],
     setup=signal_setup, runner=signal_runner(signal.SIGQUIT, 0.01, True),
     rc=(0, 1, 128 + signal.SIGQUIT), check=signal_check(signal.SIGQUIT), out="out",
     ignore_out_always=True, limit_as=False, timeout=90)


# Converters' inputs with two columns swapped (issue 42): a BLE track's RSS and a coordinate,
# an IPIN log's RSS and TxPower/Major, IPIN's beacon table (or the log's landmarks) with Lat and
# Lon swapped. Refused with the file, the line and what was expected; a single reading >= 0 dBm
# among real ones is dropped and counted (refused under --strict).
IPIN_LOCATIONS = ('bleID,Lat,Lon,floor\n"BLE1",49.46129,11.11120,00\n'
                  '"BLE2",49.46107,11.11121,00\n"BLE3",49.46129,11.11152,-2\n')


def ipin_files(ble_lines, posi="49.46128;11.11110", locations=IPIN_LOCATIONS):
    def run(ctx):
        lines = ["% a GetSensorData log"]
        for k in range(40):
            t, st = 0.01 + 0.02 * k, 100.0 + 0.02 * k
            lines += ["ACCE;%.2f;%.2f;0.1;0.2;9.8;3" % (t, st),
                      "GYRO;%.2f;%.2f;0.0;0.0;0.1;3" % (t, st),
                      "MAGN;%.2f;%.2f;10;20;30;3" % (t, st)]
        lines.append("POSI;0.5;1;%s;0;100" % posi)
        lines += ble_lines
        ctx.write("log.txt", "\n".join(lines) + "\n")
        ctx.write("BLE_Locations.csv", locations)
    return run


def ble4(rss, txpower="0", major="1", minor="2", t=0.6, n=5):
    return ["BLE4;%.2f;iBeacon;BE:AC:20:23:00:0%s;%s;%s;%s;%s;UUID" % (t + 0.1 * k, minor, rss,
                                                                       txpower, major, minor)
            for k in range(n)]


IPIN = ["convert", "ipin", "log.txt", "BLE_Locations.csv", "--out", "out"]
case("ipin-ble4-rss-and-txpower-swapped", "converters", IPIN, setup=ipin_files(ble4("0", "-70")),
     err=allof(r"log\.txt:123: field 5 \(RSS\) of the BLE4 lines is 0, not a negative BLE RSSI "
               r"in dBm, in 5 of 5 lines", r"two columns swapped\? the lines are BLE4;"))
case("ipin-ble4-rss-and-major-swapped", "converters", IPIN, setup=ipin_files(ble4("1", "0", "-70")),
     err=allof(r"log\.txt:123: field 5 \(RSS\) of the BLE4 lines is 1, not a negative BLE RSSI"))
case("ipin-ble4-rss-and-minor-swapped", "converters", IPIN,
     setup=ipin_files(["BLE4;0.60;iBeacon;BE:AC:20:23:00:02;2;0;1;-70;UUID"]),
     err=allof(r"log\.txt:123: iBeacon Minor -70 is not one of the deployed beacons"))
case("ipin-ble4-one-zero-reading-dropped", "converters", IPIN,
     setup=ipin_files(ble4("0", n=1) + ble4("-70", t=0.7)), rc=0, out="out", out_kind="walk",
     err=None, check=lambda ctx, r: [] if re.search(
         r"warning: .*log\.txt:123: BLE rss 0 dBm is not below 0 dBm.*; dropped", r.stderr) else [
         "no warning naming the dropped reading: %r" % r.stderr[:300]])
case("ipin-ble4-one-zero-reading-strict", "converters", IPIN + ["--strict"],
     setup=ipin_files(ble4("0", n=1) + ble4("-70", t=0.7)),
     err=allof(r"log\.txt:123: BLE rss 0 dBm is not below 0 dBm", r"strict conversion"))
case("ipin-locations-lat-lon-swapped", "converters", IPIN,
     setup=ipin_files(ble4("-70"), locations=IPIN_LOCATIONS.replace(
         '49.46107,11.11121', '11.11121,49.46107')),
     err=allof(r"BLE_Locations\.csv:3: BLE2 at Lat 11\.1112, Lon 49\.4611 is \d",
               r"expected every beacon within 1000 m of the walk \(Lat and Lon swapped"))
case("ipin-landmarks-lat-lon-swapped", "converters", IPIN,
     setup=ipin_files(ble4("-70"), posi="11.11110;49.46128"),
     err=allof(r"BLE_Locations\.csv:2: BLE1 .* from the first POSI landmark of log\.txt",
               r"Lat and Lon swapped in one of the two files"))

BLE_DEV = ('Dongles:{"b827eb4521b4": [[7.00, 7.09, 1.22], 1, "sensor10"], '
           '"000000000101": [[7.18, 0.68, 2.30], 2, "sensor11"], '
           '"000000000102": [[0.71, 6.16, 2.30], 3, "sensor12"]}\n'
           'Beacons:{"e78f135624ce": [[], 1328790, "beacon1"] }\n')


def ble_track(swap=None, scale=1.0, n=20):
    """A track of n lines (time, receiver, beacon, RSS, x, y, z, 9 numbers), fields `swap`
    (0-based) exchanged, x and y multiplied by `scale`."""
    def run(ctx):
        rx = ["b827eb4521b4", "000000000101", "000000000102"]
        rows = []
        for k in range(n):
            f = ["%.3f" % (1581249601.0 + 0.1 * k), rx[k % 3], "e78f135624ce", str(-70 - k % 9),
                 "%.3f" % ((2.0 + 0.2 * k) * scale), "%.3f" % (3.0 * scale), "1.8",
                 "0.06", "0", "-1", "1", "0.02", "0.06", "0.02", "-1", "0.002"]
            if swap:
                f[swap[0]], f[swap[1]] = f[swap[1]], f[swap[0]]
            rows.append(",".join(f))
        ctx.write("t.mbd", "\n".join(rows) + "\n")
        ctx.write("tetam.dev", BLE_DEV)
    return run


BLET = ["convert", "bletracks", "t.mbd", "tetam.dev", "--out", "out"]
case("bletracks-valid", "converters", BLET, setup=ble_track(), rc=0, out="out", out_kind="walk")
case("bletracks-rss-and-x-swapped", "converters", BLET, setup=ble_track((3, 4)),
     err=allof(r"t\.mbd:1: field 4 \(RSS\) is 2, not a negative BLE RSSI in dBm, in 20 of 20",
               r"two columns swapped\? the lines are time, receiver MAC, beacon MAC, RSS"))
case("bletracks-rss-and-z-swapped", "converters", BLET, setup=ble_track((3, 6)),
     err=allof(r"t\.mbd:1: field 4 \(RSS\) is 1\.8, not a negative BLE RSSI"))
case("bletracks-y-and-rss-swapped", "converters", BLET, setup=ble_track((5, 3)),
     err=allof(r"t\.mbd:1: field 4 \(RSS\) is 3, not a negative BLE RSSI"))
case("bletracks-positions-in-millimetres", "converters", BLET, setup=ble_track(scale=1000.0),
     err=allof(r"t\.mbd:1: fields 5-6 \(x, y\) is \(2000, 3000\), not a position within 30 m of "
               r"the receivers in tetam\.dev", r"in 20 of 20 lines"))
case("bletracks-receiver-and-beacon-swapped", "converters", BLET, setup=ble_track((1, 2)),
     err=allof(r"t\.mbd:1: receiver MAC 'e78f135624ce' is not a Dongle in tetam\.dev"))


def warnings_counted(ctx, r):
    """compare printed the walk's warnings and counted them in results.json."""
    problems = []
    if not re.search(r"(?m)^walkgraph: warning: w/walk\.yaml: the converter dropped 3 rss", r.stderr):
        problems.append("the dropped readings were not printed: %r" % r.stderr[:300])
    if not re.search(r"(?m)^walkgraph: warning: w/walk\.yaml: radio: eta 8 outside \[1\.5, 6\]",
                     r.stderr):
        problems.append("the unusual eta was not printed")
    try:
        with open(ctx.p("out", "results.json")) as f:
            w = json.load(f)["warnings"]
        if w.get("count") != 2 or len(w.get("messages", [])) != 2:
            problems.append("results.json warnings: %r; expected a count of 2" % (w,))
    except (OSError, ValueError, KeyError) as e:
        problems.append("results.json: %s" % e)
    return problems


case("compare-counts-warnings-in-results-json", "plausibility", CMP + ["out"],
     setup=with_walk(seq(lambda ctx: ctx.replace("w/walk.yaml", "eta: 2.5", "eta: 8"),
                         lambda ctx: ctx.append("w/walk.yaml",
                                                "extra:\n  convert.rss_invalid_dropped: 3\n"))),
     rc=0, out="out", out_kind="compare", check=warnings_counted)

def pid_namespaces_usable():
    try:
        return subprocess.run(["unshare", "-p", "-f", "--mount-proc", "true"],
                              capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def in_pid_namespace(argv, cwd, home):
    """Starts the CLI as PID 1 of a new PID namespace (the PIDs a shared folder's other writers
    have, on another node or in another container, say nothing here)."""
    env = dict(os.environ, HOME=home, LC_ALL="C")
    return subprocess.Popen(["unshare", "-p", "-f", "--mount-proc", ARGS.cli] + argv, cwd=cwd,
                            env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)


def held_lock_runner(namespace):
    """A live writer elsewhere: this script holds .out.walkgraph-lock and has a temporary named
    for PID 1 (the CLI's own PID in a new namespace). The CLI must refuse, and leave both."""
    def run(ctx):
        import fcntl
        if namespace and not pid_namespaces_usable():
            ctx.skipped = "unshare -p not permitted here"
            return Result(0, "", "", 0.0)
        ctx.mkdir(".out.walkgraph-tmp-1", {"results.json": "{\"live\": true}\n"})
        fd = os.open(ctx.p(".out.walkgraph-lock"), os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        try:
            argv = CMP + ["out"]
            if namespace:
                t0 = time.time()
                res = finish(in_pid_namespace(argv, ctx.sb, ctx.home), 60, t0)
            else:
                res = run_cli(argv, ctx.sb, ctx.home)
            ctx.live_tmp = ctx.read(".out.walkgraph-tmp-1/results.json")
        finally:
            os.close(fd)
            ctx.remove(".out.walkgraph-tmp-1")
            ctx.remove(".out.walkgraph-lock")
        return res
    return run


def held_lock_check(ctx, r):
    if getattr(ctx, "skipped", None):
        return []
    problems = []
    if getattr(ctx, "live_tmp", None) != "{\"live\": true}\n":
        problems.append("the live writer's temporary was changed or removed")
    if os.path.lexists(ctx.p("out")):
        problems.append("out was written while another writer held its lock")
    if r.rc != 1 or not re.search(allof(r"another walkgraph process", r"\.out\.walkgraph-lock"),
                                  r.stderr):
        problems.append("expected exit 1 naming the other writer's lock")
    return problems


for ns in (False, True):
    case("second-writer-refused" + ("-other-pid-namespace" if ns else ""), "shared-folders",
         CMP + ["out"], setup=walk(), runner=held_lock_runner(ns), check=held_lock_check,
         rc=(0, 1))


def two_writers_runner(ctx):
    """Two writers of one target, each PID 1 of its own PID namespace, started together, a few
    rounds: each exits 0 having written the whole target, or 1 with the lock's message."""
    if not pid_namespaces_usable():
        ctx.skipped = "unshare -p not permitted here"
        return Result(0, "", "", 0.0)
    ctx.rounds = []
    t0 = time.time()
    for _ in range(4):
        procs = [in_pid_namespace(CMP + ["out"], ctx.sb, ctx.home) for _ in range(2)]
        results = [finish(p, 60, t0) for p in procs]
        ctx.rounds.append((results, compare_output_problems(ctx.p("out"))))
    return Result(0, "", "", time.time() - t0)


def two_writers_check(ctx, r):
    if getattr(ctx, "skipped", None):
        return []
    problems = []
    for i, (results, target) in enumerate(ctx.rounds):
        for res in results:
            if res.rc == 0 and "wrote out/" not in res.stdout:
                problems.append("round %d: exit 0 without 'wrote'" % i)
            elif res.rc == 1 and not re.search(r"another walkgraph process", res.stderr):
                problems.append("round %d: the loser's message is unclear: %r" % (
                    i, res.stderr[:200]))
            elif res.rc not in (0, 1):
                problems.append("round %d: exit %s" % (i, describe_rc(res.rc)))
        if not any(res.rc == 0 for res in results):
            problems.append("round %d: neither writer wrote" % i)
        if target:
            problems.append("round %d: target not whole: %s" % (i, ", ".join(target[:3])))
    return problems


case("two-writers-two-pid-namespaces", "shared-folders", CMP + ["out"], setup=walk(),
     runner=two_writers_runner, check=two_writers_check, rc=0, out="out",
     ignore_out_always=True, timeout=300)


def output_problems(ctx, c):
    path = ctx.p(c.out)
    if c.out_kind == "tum":
        st = os.lstat(path) if os.path.lexists(path) else None
        if st is None or not stat.S_ISREG(st.st_mode):
            return ["%s is not a regular file after success" % c.out]
        with open(path, "rb") as f:
            head = f.read(200)
        return [] if head.startswith(b"#") or head[:1].isdigit() else [
            "%s does not look like a TUM trajectory" % c.out]
    if not os.path.isdir(path) or os.path.islink(path):
        return ["%s is not a folder after success" % c.out]
    problems = []
    if not os.path.isfile(os.path.join(path, MARKER)):
        problems.append("%s/%s marker missing" % (c.out, MARKER))
    if c.out_kind == "compare":
        problems += [p for p in compare_output_problems(path) if MARKER not in p]
    elif c.out_kind == "study":
        for name in ("study.csv", "study.html", "timing.csv"):
            if not os.path.isfile(os.path.join(path, name)):
                problems.append("%s/%s missing" % (c.out, name))
    elif c.out_kind == "walk":
        r = run_cli(["validate", path], ctx.sb, ctx.home, 60)
        if r.rc != 0:
            problems.append("written walk does not validate: %s" % r.stderr[:150])
    return problems


def run_case(c):
    """Runs one case in a fresh sandbox; returns (name, problems, result, elapsed, sandbox)."""
    t0 = time.time()
    sandbox = tempfile.mkdtemp(prefix="case-", dir=ARGS.root)
    os.chmod(sandbox, 0o755)
    res = None
    problems = []
    try:
        ctx = Ctx(sandbox)
        os.chmod(ctx.home, 0o755)
        try:
            if c.setup:
                c.setup(ctx)
        except SetupError as e:
            return c.name, ["setup failed: %s" % e], None, time.time() - t0, sandbox
        cwd = ctx.p(c.cwd)
        os.makedirs(cwd, exist_ok=True)
        argv = [a.format(**ctx.vars()) if "{" in a and len(a) < 200 else a for a in c.argv]
        before = snapshot(sandbox)
        watched = {w: listing(w) for w in c.watch}
        if c.runner:
            res = c.runner(ctx)
        else:
            res = run_cli(argv, cwd, ctx.home, c.timeout, c.as_nobody, c.limit_as)

        # 1. exit code
        allowed = c.rc if isinstance(c.rc, tuple) else (c.rc,)
        if res.hung:
            problems.append("hung (killed after %.0f s)" % c.timeout)
        elif res.rc not in allowed:
            problems.append("expected exit %s, got %s" % ("/".join(map(str, allowed)),
                                                          describe_rc(res.rc)))
        # 2. stderr
        if not res.hung and res.rc == 1:
            if not re.search(r"(?m)^walkgraph: ", res.stderr):
                problems.append("no 'walkgraph: ' message on stderr")
            if c.err and not re.search(c.err, res.stderr):
                problems.append("stderr does not match /%s/" % c.err)
            if c.not_err and re.search(c.not_err, res.stderr):
                problems.append("stderr matches /%s/ (should not)" % c.not_err)
        # 3. nothing else touched
        after = snapshot(sandbox)
        success = not res.hung and res.rc == 0
        ignore = list(c.may_vanish)
        if c.out and (c.ignore_out_always or (success and 0 in allowed)):
            ignore.append(os.path.normpath(c.out))
        changes = diff_snapshots(before, after, ignore)
        for rel in c.may_vanish:  # stale temporaries: removed, or at least left as they were
            if rel in after and after.get(rel) != before.get(rel):
                changes.append("changed %s" % rel)
        if changes:
            problems.append("touched outside the intended output: " + ", ".join(changes[:5]) +
                            (" (+%d more)" % (len(changes) - 5) if len(changes) > 5 else ""))
        for w, names in watched.items():
            added = listing(w) - names
            if added:
                problems.append("new entries in %s: %s" % (w, ", ".join(sorted(added)[:5])))
        # 4. temporaries
        temps = temporaries(sandbox)
        if temps:
            problems.append("temporaries left: " + ", ".join(temps[:5]))
        # 5. stderr length
        if len(res.stderr) >= MAX_STDERR:
            problems.append("stderr is %d chars (limit %d)" % (len(res.stderr), MAX_STDERR))
        # output content on success
        if success and c.out and c.out_kind and 0 in allowed:
            problems += output_problems(ctx, c)
            for rel in c.gone:
                if os.path.lexists(ctx.p(rel)):
                    problems.append("%s survived the replacement" % rel)
        if c.check and not res.hung:
            problems += c.check(ctx, res)
    except SetupError as e:
        problems.append("error: %s" % e)
    except Exception as e:  # a bug in this script: report it as a failure, keep going
        import traceback
        problems.append("test-script exception: %s" % "".join(
            traceback.format_exception_only(type(e), e)).strip())
        if ARGS.verbose:
            traceback.print_exc()
    return c.name, problems, res, time.time() - t0, sandbox


def devices_ok():
    for d in ("/dev/null", "/dev/full", "/dev/zero"):
        try:
            if not stat.S_ISCHR(os.lstat(d).st_mode):
                return "%s is no longer a character device" % d
        except OSError as e:
            return "%s: %s" % (d, e)
    return None


def remove_tree(path):
    def onerror(func, p, exc):
        try:
            os.chmod(os.path.dirname(p), 0o755)
            func(p)
        except OSError:
            pass
    shutil.rmtree(path, onerror=onerror)


def main():
    global ARGS
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", required=True, help="path to the walkgraph binary")
    ap.add_argument("--source-dir", required=True, help="walkgraph source tree")
    ap.add_argument("--keep", action="store_true", help="keep the sandboxes")
    ap.add_argument("-k", dest="filter", default=None, help="only cases whose name contains this")
    ap.add_argument("-v", "--verbose", action="store_true", help="print passing cases too")
    ap.add_argument("-j", "--jobs", type=int, default=3,
                    help="cases run in parallel (default 3; most waiting is on timeouts)")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--sanitized", action="store_true",
                    help="the CLI is an ASan/UBSan build: no address-space limit, and every "
                         "timeout multiplied by --time-scale (default 8)")
    ap.add_argument("--time-scale", type=float, default=None)
    ARGS = ap.parse_args()
    if ARGS.time_scale is None:
        ARGS.time_scale = 8.0 if ARGS.sanitized else 1.0
    ARGS.cli = os.path.abspath(ARGS.cli)
    ARGS.source_dir = os.path.abspath(ARGS.source_dir)

    cases = [c for c in CASES if not ARGS.filter or ARGS.filter in c.name]
    if ARGS.list:
        for c in cases:
            print("%-28s %s" % (c.cls, c.name))
        print("%d cases" % len(cases))
        return 0
    skipped = []
    if not IS_ROOT:  # cases whose target lies outside the sandbox need a throw-away uid
        skipped = [c for c in cases if c.as_nobody]
        cases = [c for c in cases if not c.as_nobody]
    if not cases:
        print("no cases selected")
        return 1

    ARGS.root = tempfile.mkdtemp(prefix="walkgraph-hostile-")
    os.chmod(ARGS.root, 0o755)
    t_start = time.time()
    failed, passed = [], 0
    lock = threading.Lock()
    # Signal cases first: they are the longest, and are timing-sensitive.
    order = sorted(cases, key=lambda c: 0 if c.cls == "signals" else 1)

    def report(item):
        nonlocal passed
        name, problems, res, elapsed, sandbox = item
        with lock:
            if problems:
                what = ("exit %s, stderr %r" % (describe_rc(res.rc), res.stderr[:300])
                        if res else "not run")
                line = "FAIL %s: %s [%s]" % (name, "; ".join(problems), what)
                failed.append(name)
                print(line.replace("\n", "\\n"), flush=True)
            else:
                passed += 1
                if ARGS.verbose:
                    print(("ok   %s (%.2f s) [exit %s, stderr %r]" % (
                        name, elapsed, describe_rc(res.rc) if res else "-",
                        res.stderr[:160] if res else "")).replace("\n", "\\n"), flush=True)
            if ARGS.keep:
                if ARGS.verbose or problems:
                    print("     sandbox: %s" % sandbox, flush=True)
            else:
                remove_tree(sandbox)
            broken = devices_ok()
            if broken:
                print("FATAL: %s (after case %s)" % (broken, name), flush=True)

    try:
        with ThreadPoolExecutor(max_workers=max(1, ARGS.jobs)) as pool:
            for item in pool.map(run_case, order):
                report(item)
    finally:
        if not ARGS.keep:
            remove_tree(ARGS.root)
        else:
            print("sandboxes kept under %s" % ARGS.root)
    for c in skipped:
        print("SKIP %s (needs root to run as uid %d)" % (c.name, NOBODY))
    print("%d passed, %d failed%s (%.1f s)" % (passed, len(failed),
                                               ", %d skipped" % len(skipped) if skipped else "",
                                               time.time() - t_start))
    return 0 if not failed else 1


if __name__ == "__main__":
    sys.exit(main())
