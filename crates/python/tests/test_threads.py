"""Threads, the GIL, progress and Ctrl-C."""

from __future__ import annotations

import logging
import os
import signal
import sys
import threading
import time

import numpy as np
import pytest

import relief
from conftest import FIXTURE

rng = np.random.default_rng(3)
COARSE = (np.cumsum(np.cumsum(rng.normal(size=(48, 48)), 0), 1) * 5 + 800).astype(np.float32)


def test_two_threads_give_the_single_result():
    alone = relief.amplify(COARSE, FIXTURE, 16, cell_size=60, seed=2)
    out = [None, None]

    def job(i):
        out[i] = relief.amplify(COARSE, FIXTURE, 16, cell_size=60, seed=2)

    ts = [threading.Thread(target=job, args=(i,)) for i in range(2)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    for o in out:
        assert np.array_equal(o.view(np.uint32), alone.view(np.uint32))


def test_the_gil_is_released_during_work():
    ticks = []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.01)

    t = threading.Thread(target=ticker)
    t0 = time.perf_counter()
    t.start()
    relief.amplify(COARSE, FIXTURE, 16, cell_size=60, landform=False)
    elapsed = time.perf_counter() - t0
    stop.set()
    t.join()
    # A thread that held the GIL for the whole run would leave the ticker one tick.
    assert elapsed > 0.2, elapsed
    assert len(ticks) > elapsed / 0.01 * 0.3, (len(ticks), elapsed)


def test_progress_reaches_the_callback():
    seen = []
    relief.amplify(COARSE, FIXTURE, 16, cell_size=60, progress=lambda p, d, t: seen.append((p, d, t)))
    phases = {p for p, _, _ in seen}
    assert "rasterize" in phases and "landform pass" in phases, phases
    # A phase's end is reported with its last count, however short the phase: bars end full.
    assert any(p == "rasterize" and d == t > 0 for p, d, t in seen), [
        s for s in seen if s[0] == "rasterize"
    ]
    assert all(isinstance(d, int) and isinstance(t, int) for _, d, t in seen)


def test_progress_true_draws_tqdm_bars_or_logs_without_tqdm(capsys, caplog, monkeypatch):
    pytest.importorskip("tqdm")
    relief.amplify(COARSE, FIXTURE, 4, cell_size=60, progress=True)
    err = capsys.readouterr().err
    # One bar per phase, named by it, ending full (tqdm draws "100%|" when done == total).
    assert "rasterize" in err and "100%|" in err, err[-2000:]
    # Without tqdm the same reports go to the "relief" logger.
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    with caplog.at_level(logging.INFO, logger="relief"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=60, progress=True)
    assert any("rasterize:" in r.getMessage() for r in caplog.records), caplog.text[-2000:]


def test_an_exception_in_the_callback_stops_the_run():
    class Boom(Exception):
        pass

    def cb(phase, done, total):
        raise Boom(phase)

    with pytest.raises(Boom):
        relief.amplify(COARSE, FIXTURE, 16, cell_size=60, progress=cb)


@pytest.mark.skipif(not hasattr(signal, "pthread_kill"), reason="POSIX signals")
def test_ctrl_c_stops_a_long_run_within_a_second():
    big = np.tile(COARSE, (6, 6))  # 288 x 288 -> 18432 x 18432 cells with 6 levels (~6 s)
    rendering = threading.Event()
    finished = threading.Event()
    sent = []

    def progress(phase, done, total):
        if done > 0:
            rendering.set()

    def interrupt():
        # Once the synthesis runs (tens of seconds uninterrupted), as a user's Ctrl-C would.
        if rendering.wait(60) and not finished.is_set():
            time.sleep(0.2)
            sent.append(time.perf_counter())
            os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=interrupt)
    t.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            relief.refine(big, cell_size=60, extra_levels=6, landform=False, progress=progress)
        returned = time.perf_counter()
    finally:
        finished.set()
        rendering.set()
        t.join()
    assert sent, "the synthesis never reported progress"
    assert returned - sent[0] < 1.0, returned - sent[0]
