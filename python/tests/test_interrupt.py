"""Ctrl-C (SIGINT) interrupts a long reconstruction or calibration promptly
with KeyboardInterrupt."""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import cassi

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


@pytest.fixture(autouse=True)
def ctrl_c_raises():
    """Python raises KeyboardInterrupt on SIGINT only when it started with
    the default disposition; a process started in the background by a
    shell without job control (as CI may be) inherits SIGINT ignored.
    Install the interactive handler for the test, whatever the parent did."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_sigint_from_a_thread_stops_a_long_reconstruction():
    mask = cassi.random_mask(128, 128, seed=1)
    y = cassi.simulate(cassi.synthetic_scene(128, 128, 28, seed=1), mask, noise=False)
    sent = []

    def send():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(0.5, send)
    timer.start()
    started = time.perf_counter()
    def too_long(info):
        # fail instead of hanging if the signal is not seen
        assert info["elapsed_s"] < 10, "SIGINT did not stop the reconstruction"

    with pytest.raises(KeyboardInterrupt):
        # 100,000 iterations would take many minutes
        cassi.reconstruct(y, mask, iterations=100_000, progress=too_long)
    ended = time.perf_counter()
    timer.join()
    assert sent, "the signal was never sent"
    assert ended - sent[0] < 1.0, f"{ended - sent[0]:.2f} s after SIGINT"
    assert ended - started < 5.0


CHILD = r"""
import signal, sys, time
import cassi
signal.signal(signal.SIGINT, signal.default_int_handler)  # see ctrl_c_raises
mask = cassi.random_mask(256, 256, seed=1)
scene = cassi.synthetic_scene(256, 256, 28, seed=1)
y = cassi.simulate(scene, mask, "paper", model="subpixel")
print("ready", flush=True)
t = time.perf_counter()
cal = cassi.calibrate(y, mask)
print("finished", time.perf_counter() - t, flush=True)
"""


def test_sigint_stops_a_long_calibration_promptly():
    child = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        time.sleep(1.0)  # well inside the calibration (several seconds on 2 cores)
        child.send_signal(signal.SIGINT)
        sent = time.perf_counter()
        out, err = child.communicate(timeout=30)
        took = time.perf_counter() - sent
    finally:
        if child.poll() is None:
            child.kill()
    assert "finished" not in out, f"the calibration ended before the signal: {out}"
    assert "KeyboardInterrupt" in err, err
    assert child.returncode != 0
    assert took < 1.5, f"{took:.2f} s after SIGINT"


def test_sigint_stops_a_study_after_the_scene_and_resume_goes_on(tmp_path):
    """Ctrl-C during `evaluate` ends it once the scene in progress is
    written (no report); `resume=True` reuses the finished scenes."""
    sent = []

    def send():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    common = dict(synthetic=8, size=64, iterations=15)
    timer = threading.Timer(0.5, send)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        cassi.evaluate(tmp_path, **common)
    ended = time.perf_counter()
    timer.join()
    assert sent, "the signal was never sent"
    assert ended - sent[0] < 5.0, f"{ended - sent[0]:.2f} s after SIGINT"
    assert not (tmp_path / "report.md").exists()
    finished = sorted(p.name for p in (tmp_path / ".pending" / "scenes").glob("*.json"))
    assert 0 < len(finished) < 8, finished
    messages = []
    cassi.evaluate(tmp_path, resume=True, **common,
                   progress=lambda p: messages.append(p))
    assert (tmp_path / "report.md").is_file()
    assert len(list((tmp_path / "scenes").glob("*.json"))) == 8
    evaluating = [m for m in messages if m["stage"] == "evaluating"]
    assert evaluating and evaluating[-1]["done"] == evaluating[-1]["total"]
