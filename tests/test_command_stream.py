"""The arm command stream: a process of its own that keeps sending while this one is busy (an LCM log file
stands for the bus: no network)."""

import time

import lcm
import numpy as np
import pytest
from drake import lcmt_iiwa_command

from diagrams.benchmarks.command_stream import benchmark
from systems.robot_io.command_stream import CommandStream, CommandStreamSender

PERIOD_S = 0.005


def _sent(log_path):
    events = list(lcm.EventLog(str(log_path), "r")) if log_path.is_file() else []
    return [(event.timestamp / 1e6, lcmt_iiwa_command.decode(event.data)) for event in events]


@pytest.mark.slow
def test_stream_sends_nothing_before_a_command_then_every_period_while_this_process_is_busy(tmp_path):
    log_path = tmp_path / "commands.lcmlog"
    stream = CommandStream(f"file://{log_path}?mode=w", "CENTAURO_COMMAND", 14, PERIOD_S)
    stream.start()
    time.sleep(2.0)  # the streamer is up (it imports pydrake first), but there is nothing to send yet
    assert stream.running and stream.sends == 0
    stream.set(1_000_000, np.arange(14.0))
    end = time.monotonic() + 1.0
    while time.monotonic() < end:  # this process holds its interpreter, as a long planning call does
        pass
    stream.set(2_000_000, np.ones(14))
    time.sleep(0.05)
    stream.stop()
    assert not stream.running
    sent = _sent(log_path)
    times = np.array([t for t, _ in sent])
    assert len(sent) == stream.sends and 170 <= len(sent) <= 215  # 1.05 s at 200 Hz, a few sends lost to late wakes
    # No stall while this process is busy: a stream that waited for it would show one gap of its whole second and
    # send nothing in it. Per-send jitter is the VM's, not the stream's (it wakes a lone real-time loop late now and
    # then, hypervisor steal: scripts/benchmark_command_stream.py measured 15 of 11886 sends late beside busy
    # processes, up to 27 ms; CI once saw 3 of 200 sends 10-14 ms apart): at most 5 % of the sends later than two
    # periods, none later than 20 periods (0.1 s, a tenth of the busy second).
    gaps = np.diff(times)
    assert np.count_nonzero(gaps > 2 * PERIOD_S) <= 0.05 * len(gaps), gaps[gaps > 2 * PERIOD_S]
    assert gaps.max() <= 20 * PERIOD_S and stream.max_gap_s <= 20 * PERIOD_S
    first, last = sent[0][1], sent[-1][1]
    assert first.utime == 1_000_000 and first.num_joints == 14 and list(first.joint_position) == list(range(14))
    assert last.utime == 2_000_000 and list(last.joint_position) == [1.0] * 14


def test_sender_system_hands_the_guards_command_to_the_stream(tmp_path):
    stream = CommandStream(f"file://{tmp_path / 'c.lcmlog'}?mode=w", "CMD", 14, PERIOD_S)
    dut = CommandStreamSender(stream, PERIOD_S, 0.0)
    context = dut.CreateDefaultContext()
    dut.get_input_port().FixValue(context, np.full(14, 0.5))
    context.SetTime(0.25)
    dut.ForcedPublish(context)
    deadline = time.monotonic() + 30  # (the streamer imports pydrake first)
    while stream.sends < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    stream.stop()
    sent = _sent(tmp_path / "c.lcmlog")
    assert sent and sent[-1][1].utime == 250_000 and list(sent[-1][1].joint_position) == [0.5] * 14


@pytest.mark.slow
def test_stream_benchmark_reports_idle_and_loaded_runs():
    runs = benchmark(1.5, 1)["runs"]
    assert [run["busy_processes"] for run in runs] == [0, 1]
    for run in runs:  # the streamer needs about 0.5 s to start; then it sends every 5 ms
        assert 100 < run["sent"] <= 1.5 / PERIOD_S + 1 and run["max_gap_s"] >= PERIOD_S * 0.9


def test_the_streamer_never_waits_for_a_writer_caught_mid_write():
    """A writer preempted between its two version increments (odd version) must not hold the real-time reader:
    it sends the last consistent command again."""
    from systems.robot_io.command_stream import _Q, _VERSION, _read

    shared = np.zeros(_Q + 14)
    shared[_VERSION], shared[_Q:] = 2.0, 1.0
    first = _read(shared, None)
    np.testing.assert_array_equal(first[_Q:], np.ones(14))
    shared[_VERSION], shared[_Q:] = 3.0, 7.0  # mid-write
    np.testing.assert_array_equal(_read(shared, first)[_Q:], np.ones(14))
    assert _read(shared, None) is None  # nothing consistent yet: nothing to send
