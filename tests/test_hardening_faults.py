"""Faults (issue 7, part 3), beyond what tests/test_daemon*.py already cover.

Already covered elsewhere and not repeated: a raising or NaN-returning restyler fades to
pass-through with no pop (test_daemon.py), a stalled replay source holds and is
reported lost (test_daemon.py), fan-out past a vanished receiver at the sender level
(test_vmc_out.py), SIGTERM leaves a valid recording (test_daemon_cli.py), repair after a
hand-cut file (test_daemon_recorder.py).

Added here: the fallback starts on the very first frame a failed word should have
served, reaches exact pass-through and blends back, for every kind of bad result; a slow
model under the real clock never holds up the output clock; a hung model does not make
the inference queue grow without bound; a live VMC source that stops is held and then
shown as lost in the log line and the OSC status; a receiver that vanishes in the middle
of a daemon run costs the others nothing; Ctrl-C (SIGINT to the process group) closes a
valid recording; ``kill -9`` at a known frame loses at most a second and
``stylecast repair`` restores a file whose frames are exactly those sent.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from stylecast.motion.clock import FakeClock, RealClock
from stylecast.daemon.config import DaemonConfig
from stylecast.daemon.engine import Daemon
from stylecast.daemon.inference import InferenceWorker
from stylecast.daemon.restylers import IdentityRestyler, StandInRestyler
from stylecast.daemon.status import status_messages
from stylecast.drivers.bvh.bvh_replay import ReplaySource
from stylecast.drivers.sources import open_source
from stylecast.drivers.vmc.vmc_parse import VmcParser
from stylecast.drivers.vmc.vmc_out import encode_frame
from stylecast.motion import rotations as rot
from stylecast.motion.smoothing import CORRECTION_TAU
from stylecast.motion.words import first_word_end
from stylecast.motion.humanoid import HUMANOID_BONES, humanoid_skeleton_default

from .test_daemon import walk_clip

J = len(HUMANOID_BONES)
REPO = Path(__file__).resolve().parents[1]
HOP = 15
CROSSFADE = 30  # frames (the default 0.5 s)


class Faulty:
    """The stand-in restyler, except that calls in ``bad`` fail in the way ``kind`` says."""

    def __init__(self, kind: str, bad: range):
        self.kind, self.bad, self.calls = kind, bad, 0
        self.good = StandInRestyler()

    def restyle_words(self, words):
        self.calls += 1
        out = self.good.restyle_words(words)
        if self.calls not in self.bad:
            return out
        if self.kind == "raise":
            raise RuntimeError("model exploded")
        if self.kind == "nan":
            out[:, 30, 4, 1] = np.nan
        elif self.kind == "inf":
            out[:, :, 0] = np.inf
        elif self.kind == "zeros":
            out[:, 10] = 0.0
        elif self.kind == "shape":
            return out[:, :59]
        elif self.kind == "none":
            return None
        return out


@pytest.mark.parametrize("kind", ["raise", "nan", "inf", "zeros", "shape", "none"])
def test_a_failed_word_falls_back_on_its_first_frame_reaches_pass_through_and_blends_back(kind):
    clip = walk_clip(600)
    bad = range(5, 12)  # 7 consecutive words fail: a 105-frame outage, longer than the fade
    restyler = Faulty(kind, bad)
    record = []

    frames = []
    daemon = Daemon(DaemonConfig(hop=HOP, control="off"), [ReplaySource(clip, "p0")], restyler, FakeClock(),
                    frame_taps=[frames.append], log_status=False)
    s = daemon.sessions[0]
    daemon.start()
    while not daemon.finished:
        daemon.step()
        record.append((s.blender.mix, s.blender.late_frames))
    daemon.close()
    # One performer under a virtual clock: call k restyles exactly the word ending at
    # first_word_end + HOP * (k - 1), which serves frames end - HOP + 1 .. end.
    first_bad_end = first_word_end(HOP) + HOP * (bad.start - 1)
    first_good_end = first_word_end(HOP) + HOP * (bad.stop - 1)
    t_fail, t_back = first_bad_end - HOP + 1, first_good_end - HOP + 1
    out = np.stack([f.rotations for f in frames])
    assert [f.index for f in frames] == list(range(clip.num_frames))
    mix = np.array([m for m, _ in record[-len(frames):]])
    late = np.array([n for _, n in record[-len(frames):]])
    assert daemon.worker.faults == len(bad) and s.words_failed == len(bad)
    # Within one frame: the first frame the failed word should serve is counted late and
    # already fades towards pass-through; the frame before was fully restyled.
    assert mix[t_fail - 1] == 1.0 and mix[t_fail] == pytest.approx(1.0 - 1.0 / CROSSFADE)
    assert late[t_fail] == 1 and late[t_fail - 1] == 0
    # It reaches pass-through exactly (output == input) while the outage lasts, once the
    # fade and the correction low-pass after it have settled (25 time constants: 5e-9 of
    # the correction left)...
    passthrough = slice(t_fail + CROSSFADE + int(25 * CORRECTION_TAU), t_back)
    assert passthrough.stop - passthrough.start > 10
    assert (mix[passthrough] == 0.0).all()
    assert rot.angle_between(out[passthrough], clip.rotations[passthrough]).max() < 1e-6
    # ...and blends back once good words return, starting on their first frame.
    assert mix[t_back] == pytest.approx(1.0 / CROSSFADE) and (mix[t_back + CROSSFADE:] == 1.0).all()
    assert rot.angle_between(out[-60], clip.rotations[-60]).max() > 1.0  # restyled again
    # No pop on the way out or back: frame-to-frame motion stays within the input's own
    # motion plus a small bound.
    assert np.isfinite(out).all()
    steps = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    in_steps = rot.angle_between(clip.rotations[1:], clip.rotations[:-1]).max(axis=1)
    assert (steps - in_steps).max() < 2.0


def test_a_slow_model_never_holds_up_the_real_output_clock():
    clip = walk_clip(300)
    slow_calls = (4, 5)
    windows = []

    class Slow:
        calls = 0

        def restyle_words(self, words):
            Slow.calls += 1
            if Slow.calls in slow_calls:
                t0 = time.monotonic()
                time.sleep(0.7)
                windows.append((t0, time.monotonic()))
            return StandInRestyler().restyle_words(words)

    emitted = []  # (wall time, index, mix, rotations)
    daemon = Daemon(DaemonConfig(hop=HOP, control="off"), [ReplaySource(clip, "p0", loop=True)], Slow(),
                    RealClock(), log_status=False,
                    frame_taps=[lambda f: emitted.append((time.monotonic(), f.index, daemon.sessions[0].blender.mix,
                                                          f.rotations))])
    try:
        daemon.run(duration=5.0)
    finally:
        daemon.close()
    s = daemon.sessions[0]
    assert len(windows) == 2 and s.blender.late_frames > 0
    # While the model slept, the clock kept emitting frames (a tick every 16.7 ms; even a
    # machine this busy gets several of them out in 0.7 s).
    for t0, t1 in windows:
        during = [e for e in emitted if t0 < e[0] < t1]
        assert len(during) >= 5, (len(during), daemon.dropped_ticks)
    # Blended back by the end, and every emitted frame continues the previous one.
    assert emitted[-1][2] == 1.0
    idx = np.array([e[1] for e in emitted])
    assert (np.diff(idx) >= 1).all()
    out = np.stack([e[3] for e in emitted])
    src = np.stack([clip.rotations[i % clip.num_frames] for i in idx])
    steps = rot.angle_between(out[1:], out[:-1]).max(axis=1)
    in_steps = rot.angle_between(src[1:], src[:-1]).max(axis=1)
    assert (steps - in_steps).max() < 2.5


def test_a_hung_model_does_not_grow_the_inference_queue_without_bound():
    release = threading.Event()
    batches = []

    class Hung:
        def restyle_words(self, words):
            batches.append(len(words))
            release.wait(30)
            return np.array(words)

    worker = InferenceWorker(Hung())
    word = np.tile([0.0, 0.0, 0.0, 1.0], (60, J, 1))
    try:
        worker.submit([(0, 59, word)])
        deadline = time.monotonic() + 10
        while not batches and time.monotonic() < deadline:
            time.sleep(0.005)
        for k in range(1, 2001):  # 2000 ticks' worth of words while the model hangs (33 s of show)
            worker.submit([(0, 59 + k, word), (1, 59 + k, word)])
        waiting = sum(len(job) for job in worker._jobs)
        _, failed = worker.collect()
        release.set()
        assert worker.wait_idle(30)
        done, failed_after = worker.collect()
    finally:
        release.set()
        worker.close()
    # Words that could no longer be shown in time were given up (each counted as failed,
    # so the blender shows pass-through), instead of piling up behind the hung call.
    assert waiting <= 64, waiting
    assert len(failed) + len(failed_after) + len(done) == 1 + 2 * 2000
    assert max(batches[1:]) <= 64  # the catch-up call after the hang is bounded too
    assert {end for _, end, _ in done} >= {59 + 2000}  # the newest words were kept


# ------------------------------------------------------------ a live source that stops

def _wait(predicate, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.001)
    return predicate()


def test_a_live_vmc_source_that_stops_is_held_then_reported_lost_then_resumes():
    clip = walk_clip(400)
    src = open_source("vmc://127.0.0.1:0?name=alice", "p0")
    frames = []
    daemon = Daemon(DaemonConfig(hop=HOP, control="off"), [src], IdentityRestyler(), FakeClock(),
                    frame_taps=[frames.append], log_status=False)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    offsets = humanoid_skeleton_default().offsets
    sent = 0

    def send_one():
        nonlocal sent
        for d in encode_frame(clip.root_positions[sent], clip.rotations[sent], offsets, float(sent)):
            sender.sendto(d, src.receiver.address)
        sent += 1
        # handed over to the daemon (not merely parsed): the next tick will poll it
        assert _wait(lambda: len(src.receiver._queue) >= 1)

    lost, lines, status = [], [], []
    try:
        daemon.start()
        for phase, ticks in (("live", 150), ("silent", 100), ("back", 60)):
            for _ in range(ticks):
                if phase != "silent":
                    send_one()
                daemon.step()
                lost.append(daemon.sessions[0].lost)
            lines.append(daemon.status_lines()[0])
            status.append(dict(zip(("name", "in", "out", "p50", "p99", "late", "held", "skipped", "failed",
                                    "intensity", "bypass", "lost"),
                                   status_messages(daemon.snapshot())[1][1])))
    finally:
        daemon.close()
        sender.close()
    s = daemon.sessions[0]
    assert not any(lost[:150]) and not any(lost[150:150 + 59]) and all(lost[150 + 60:250])
    assert not any(lost[250 + 1:])
    assert "LOST" not in lines[0] and "alice LOST (no input)" in lines[1] and "LOST" not in lines[2]
    assert [st["lost"] for st in status] == [0, 1, 0]
    # While silent the avatar holds its last pose (same frame, no hip jump), one per tick.
    # (A held tick re-sends the previous frame object.)
    repeats = [k for k in range(1, len(frames)) if frames[k] is frames[k - 1]]
    assert len(repeats) == s.held and s.held >= 100 - HOP - 1
    last = frames[repeats[0] - 1]
    # Output runs HOP frames behind input, so it holds the frame shown when input stopped
    # and, when input returns, carries on from the next one (nothing skipped).
    assert last.index == 150 - 1 - HOP
    assert frames[repeats[-1] + 1].index == last.index + 1 and s.skipped == 0
    for k in repeats:
        np.testing.assert_array_equal(frames[k].rotations, last.rotations)
        np.testing.assert_array_equal(frames[k].root_position, last.root_position)
    assert len(frames) == daemon.ticks - HOP  # a frame on every tick, held or new


# ------------------------------------------------- a receiver vanishes mid-run

def test_a_receiver_that_vanishes_mid_run_costs_the_others_nothing():
    live = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    doomed = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for s in (live, doomed):
        s.bind(("127.0.0.1", 0))
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        s.setblocking(False)
    ports = [s.getsockname()[1] for s in (doomed, live)]  # the dead one first: its errors come first
    cfg = DaemonConfig(hop=HOP, control="off", out=[f"vmc://127.0.0.1:{p}" for p in ports])
    daemon = Daemon(cfg, [ReplaySource(walk_clip(300), "p0", loop=True)], StandInRestyler(), FakeClock(),
                    log_status=False)
    got = []
    try:
        daemon.start()
        for k in range(240):
            if k == 60:
                doomed.close()  # the receiver process died: ICMP port unreachable from now on
            daemon.step()
            while True:
                try:
                    got.append(live.recv(65536))
                except BlockingIOError:
                    break
        counters = daemon.sinks[0].vmc.counters()
    finally:
        daemon.close()
        live.close()
    parser = VmcParser("check")
    frames = [f for d in got for f in parser.feed(d, ("127.0.0.1", 1), 0.0)]
    sent = counters["frames_sent"]
    assert sent == 240 - HOP and len(frames) == sent
    np.testing.assert_allclose([f.sender_time for f in frames], np.arange(HOP, 240) / 60.0, atol=1e-5)
    per = counters["targets"]
    assert per[f"127.0.0.1:{ports[1]}"] == {"sent": 2 * sent, "errors": {}}
    if sys.platform.startswith("linux"):
        assert sum(per[f"127.0.0.1:{ports[0]}"]["errors"].values()) > 0


# --------------------------------------------------------- Ctrl-C and kill -9

def _walk_file(tmp_path) -> Path:
    from stylecast.motion.bvh import write_bvh

    path = tmp_path / "walk.bvh"
    write_bvh(walk_clip(240), path)
    return path


def test_ctrl_c_closes_a_valid_recording(tmp_path):
    from stylecast.motion.bvh import read_bvh

    out = tmp_path / "rec.bvh"
    proc = subprocess.Popen([sys.executable, "-m", "stylecast", "serve", "--source", f"bvh://{_walk_file(tmp_path)}?loop=1",
                             "--model", "identity", "--record", str(out), "--control", "off",
                             "--status-interval", "0.5"],
                            cwd=REPO, stderr=subprocess.PIPE, text=True, start_new_session=True)
    lines = []
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        lines.append(line)
        if "serving" in line or not line:
            break
    time.sleep(1.5)
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal's Ctrl-C does: the whole process group
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:  # say where it stuck: every line it wrote (once seen in CI)
        proc.kill()
        _, err = proc.communicate()
        pytest.fail("serve ignored Ctrl-C for 60 s; it wrote:\n" + "".join(lines) + err)
    err = "".join(lines) + err
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert "recording closed" in err and "final: p0: in" in err
    clip = read_bvh(out)  # the strict reader: the header's frame count matches the rows
    assert clip.num_frames > 30


def test_kill_9_at_a_known_frame_loses_at_most_a_second_and_stylecast_repair_fixes_it(tmp_path):
    from stylecast.motion.bvh import read_bvh

    path = tmp_path / "live.bvh"
    clip = walk_clip(120)
    kill_at = 150
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(REPO)!r})
        from stylecast.motion.clock import RealClock
        from stylecast.daemon.config import DaemonConfig
        from stylecast.daemon.engine import Daemon
        from stylecast.daemon.restylers import IdentityRestyler
        from stylecast.drivers.bvh.bvh_replay import ReplaySource
        from tests.test_daemon import walk_clip
        count = [0]
        def tap(frame):
            count[0] += 1  # called after the recorder got the frame
            if count[0] == {kill_at}:
                print(count[0], frame.index, flush=True)
                sys.stdin.readline()  # hold the output loop here until killed
        d = Daemon(DaemonConfig(hop=15, control="off", record={str(path)!r}),
                   [ReplaySource(walk_clip(120), "p0", loop=True)], IdentityRestyler(), RealClock(),
                   frame_taps=[tap], log_status=False)
        d.run(duration=60)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stdout.readline()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    appended, last_index = map(int, line.split())
    assert appended == kill_at
    with pytest.raises(Exception):
        read_bvh(path)  # the count in the header is still 0: not a valid file yet
    r = subprocess.run([sys.executable, "-m", "stylecast", "repair", str(path)], cwd=REPO, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    repaired = read_bvh(path)
    kept = repaired.num_frames
    assert f"{kept} frames kept" in r.stdout
    assert kill_at - 60 <= kept <= kill_at  # at most the last second lost
    # The frames kept are exactly the frames sent (identity restyler: output == input).
    indices = np.arange(last_index - appended + 1, last_index - appended + 1 + kept) % clip.num_frames
    assert rot.angle_between(repaired.rotations, clip.rotations[indices]).max() < 1e-3
    np.testing.assert_allclose(repaired.root_positions, clip.root_positions[indices], atol=1e-5)
