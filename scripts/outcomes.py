"""Run inputs as a user would and sort what happens: the harness of ``scripts/gltf_corpus.py`` and
``scripts/hostile_inputs.py``.

A case is a command line of ``warp-sg`` (``{"argv": [...]}``) or a Python snippet using the
public API (``{"python": "..."}``, run with ``import warp_sg as ws`` done). Cases run one after the
other in a worker process (``python scripts/outcomes.py --worker``: Warp's kernels compile once),
each with its own time limit; a case that runs past it is a **hang** (the worker is killed and a
new one started), a worker that dies is a **kill** (e.g. the kernel's out-of-memory killer). Every
byte a case writes to its stdout and stderr is captured at the file-descriptor level (so a C
library's prints count too). The outcome of a case:

* ``rendered`` — exit status 0 (CLI) or no exception (Python), its output written;
* ``refused`` — exit status 2 and exactly one stderr line ``warp-sg: error: ...`` (Python: an
  ``InputError`` whose message is one line), no output file left behind;
* ``traceback`` — an exception other than ``InputError`` left the command (or ``Traceback`` on stderr);
* ``noise`` — a refusal or a render that printed more than its one error line and its
  ``warp-sg: warning:`` lines (an argparse usage, a library's diagnostics);
* ``hang`` / ``kill`` — as above.

A message that quotes an exception class (``KeyError: 'uri'``, ``AssertionError``) instead of the
user's words is flagged ``internal`` (:data:`INTERNAL`). Warp's one line about a missing CUDA
driver (machines without a GPU) is not counted as noise.
"""
from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: an exception class quoted in a message (``KeyError: 'uri'``, ``UnboundLocalError``, ``AssertionError``)
INTERNAL = re.compile(r"\b[A-Z][A-Za-z]*(Error|Exception|Warning)\b(?!s)|Traceback|\bNoneType\b")
#: lines that are not the case's own (Warp's banner on machines without a CUDA driver)
IGNORED = (re.compile(r"^Warp CUDA warning: Could not find or load the NVIDIA CUDA driver"),
           re.compile(r"^Warp \d+\.\d+\.\d+ initialized"), re.compile(r"^\s+(CUDA|Kernel cache|Devices|\"cpu\")"))


@dataclass
class Outcome:
    name: str
    outcome: str  # rendered | refused | traceback | noise | hang | kill
    rc: int | None = None
    error: str = ""  # the refusal line (or the exception)
    warnings: list = field(default_factory=list)
    noise: list = field(default_factory=list)  # other lines
    seconds: float = 0.0
    internal: bool = False  # the message quotes an exception class
    left_output: bool = False  # a refusal that left its output file

    def as_dict(self) -> dict:
        return dict(self.__dict__)


# --------------------------------------------------------------------------------------------
# worker side
# --------------------------------------------------------------------------------------------
def _run_case(case: dict) -> dict:
    """Run one case with fds 1 and 2 captured; ``{"rc", "exception", "text", "seconds"}``."""
    sys.stdout.flush()
    sys.stderr.flush()
    cap = tempfile.TemporaryFile()
    saved = os.dup(1), os.dup(2)
    os.dup2(cap.fileno(), 1)
    os.dup2(cap.fileno(), 2)
    rc, exc = None, None
    t0 = time.perf_counter()
    old_out, old_err = sys.stdout, sys.stderr
    sys.stdout = io.TextIOWrapper(os.fdopen(os.dup(1), "wb"), write_through=True)
    sys.stderr = io.TextIOWrapper(os.fdopen(os.dup(2), "wb"), write_through=True)
    try:
        if "argv" in case:
            from warp_sg.tools.cli import main

            try:
                rc = main(case["argv"])
            except SystemExit as e:  # argparse
                rc = e.code if isinstance(e.code, int) else 1
        else:
            import warp_sg as ws
            from warp_sg.core.errors import InputError

            try:
                exec(case["python"], {"ws": ws, "np": __import__("numpy"), "__name__": "case"})
                rc = 0
            except InputError as e:
                rc, exc = 2, ("InputError", str(e))
    except BaseException as e:  # noqa: BLE001 - what escapes is the finding
        exc = (type(e).__name__, "".join(traceback.format_exception_only(type(e), e)).strip()[:2000])
        rc = -1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        sys.stdout, sys.stderr = old_out, old_err
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        os.close(saved[0])
        os.close(saved[1])
    cap.seek(0)
    text = cap.read().decode("utf-8", "replace")
    cap.close()
    return {"rc": rc, "exception": exc, "text": text[-20000:], "seconds": time.perf_counter() - t0}


def worker() -> None:
    """Read one JSON case per line on stdin, answer one JSON result per line on the real stdout."""
    out = os.fdopen(os.dup(1), "w")
    for line in sys.stdin:
        if not line.strip():
            continue
        res = _run_case(json.loads(line))
        out.write(json.dumps(res) + "\n")
        out.flush()


# --------------------------------------------------------------------------------------------
# parent side
# --------------------------------------------------------------------------------------------
class Runner:
    """A worker process that runs cases; restarted after a hang or a kill."""

    def __init__(self, env: dict | None = None):
        self.env = dict(os.environ, **(env or {}))
        self.env["PYTHONPATH"] = os.pathsep.join([str(ROOT), self.env.get("PYTHONPATH", "")]).strip(os.pathsep)
        self.proc = None

    def _start(self):
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--worker"], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=self.env,
                                     cwd=self.env.get("OUTCOMES_CWD", str(ROOT)))

    def close(self):
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait()
            self.proc = None

    def run(self, name: str, case: dict, timeout: float = 120.0, output: str | None = None) -> Outcome:
        import selectors

        if self.proc is None or self.proc.poll() is not None:
            self._start()
        if output:
            Path(output).unlink(missing_ok=True)
        t0 = time.perf_counter()
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout)
        sel.close()
        if not ready:
            self.close()
            return Outcome(name, "hang", seconds=time.perf_counter() - t0)
        line = self.proc.stdout.readline()
        if not line:
            rc = self.proc.wait()
            self.proc = None
            return Outcome(name, "kill", rc=rc, seconds=time.perf_counter() - t0)
        return classify(name, json.loads(line), output)


def classify(name: str, res: dict, output: str | None) -> Outcome:
    lines = [x.rstrip() for x in res["text"].replace("\r", "\n").splitlines() if x.strip()]
    lines = [x for x in lines if not any(p.search(x) for p in IGNORED)]
    errors = [x for x in lines if x.startswith("warp-sg: error:")]
    warns = [x for x in lines if x.startswith("warp-sg: warning:")]
    other = [x for x in lines if x not in errors and x not in warns]
    o = Outcome(name, "rendered", rc=res["rc"], warnings=warns, noise=other, seconds=res["seconds"])
    exc = res["exception"]
    if exc is not None and exc[0] != "InputError":
        o.outcome, o.error = "traceback", exc[1]
    elif any("Traceback" in x for x in lines):
        o.outcome, o.error = "traceback", "\n".join(other[-3:])
    elif res["rc"] == 2:
        o.error = exc[1] if exc is not None else (errors[0] if errors else "")
        one = (len(errors) == 1 and not other) if exc is None else ("\n" not in o.error and not other)
        o.outcome = "refused" if one else "noise"
        o.left_output = bool(output) and Path(output).exists()
    elif res["rc"] != 0:
        o.outcome, o.error = "noise", "\n".join(lines[-3:])
    elif other:
        o.outcome = "noise"
    o.internal = bool(INTERNAL.search(o.error))
    return o


def summary(outcomes: list[Outcome]) -> dict:
    """Counts of each outcome, and of refusals quoting an exception class or leaving an output."""
    from collections import Counter

    c = Counter(o.outcome for o in outcomes)
    c["internal"] = sum(o.internal for o in outcomes)
    c["left_output"] = sum(o.left_output for o in outcomes)
    c["total"] = len(outcomes)
    return dict(c)


if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        worker()
    else:
        sys.exit("usage: python scripts/outcomes.py --worker (started by gltf_corpus.py / hostile_inputs.py)")
