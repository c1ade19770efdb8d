"""The control loop's thread (control/servo_sampler.py): idle period, a goal's control
period, woken at once by a goal, stopped at once."""

from __future__ import annotations

import math
import threading

import pytest

from tactile_sensor.control.grasp import GraspConfig
from tactile_sensor.control.servo_link import Poll, ServoLink
from tactile_sensor.control.servo_sampler import ServoSampler
from tactile_sensor.hardware.errors import CommunicationTimeout
from tactile_sensor.hardware.xm430 import ServoState

PATIENCE_S = 60.0


class CountingServo:
    """Answers every read; counts them. ``moving``: the reads say Moving."""

    def __init__(self) -> None:
        self.reads = 0
        self.moving = False
        self.fault: Exception | None = None

    def read_state(self) -> ServoState:
        self.reads += 1
        if self.fault is not None:
            raise self.fault
        return ServoState(math.pi, 0.0, 0.1, 12.0, 30.0, self.moving, frozenset())


class Loop:
    def __init__(self, idle_period_s: float = 3600.0, period_s: float = 0.001) -> None:
        self.client = CountingServo()
        self.link = ServoLink(self.client, GraspConfig(), period_s=period_s, retries=0)
        self.polls: list[Poll] = []
        self.order: list[str] = []
        self.sampled = threading.Condition()
        self.sampler = ServoSampler(self.link, idle_period_s=idle_period_s,
                                    before=lambda: self.order.append("before"),
                                    after=self._after)

    def _after(self, poll: Poll) -> None:
        with self.sampled:
            self.order.append("after")
            self.polls.append(poll)
            self.sampled.notify_all()

    def wait_for(self, count: int) -> None:
        with self.sampled:
            assert self.sampled.wait_for(lambda: len(self.polls) >= count, PATIENCE_S), (
                f"{len(self.polls)} samples of {count}")


def test_idle_it_samples_once_then_waits_for_its_idle_period():
    loop = Loop()
    loop.sampler.start()
    loop.wait_for(1)
    assert loop.sampler.period_s == 3600.0
    loop.sampler.stop()  # at once, although the next idle sample is an hour away
    assert not loop.sampler.running
    assert loop.client.reads == 1 and loop.order == ["before", "after"]


def test_a_goal_wakes_it_at_once_and_is_sampled_every_control_period():
    loop = Loop()
    loop.sampler.start()
    loop.wait_for(1)
    with loop.sampler.busy():
        assert loop.sampler.period_s == 0.001
        loop.wait_for(30)  # an hour's idle period would never get here
    assert loop.sampler.period_s == 3600.0
    loop.sampler.stop()
    assert loop.order[:4] == ["before", "after", "before", "after"]


def test_an_unreachable_servo_is_a_sample_that_says_so_and_the_loop_goes_on():
    loop = Loop()
    loop.client.fault = CommunicationTimeout("no status packet")
    loop.sampler.start()
    with loop.sampler.busy():
        loop.wait_for(3)
    loop.sampler.stop()
    assert loop.polls[0].state is None and loop.polls[0].lost
    assert not loop.polls[1].lost and "no status packet" in loop.polls[1].error


def test_stop_and_start_again():
    loop = Loop()
    loop.sampler.stop()  # never started: nothing to do
    loop.sampler.start()
    loop.sampler.start()  # running already: one thread
    loop.wait_for(1)
    loop.sampler.stop()
    loop.sampler.start()
    loop.wait_for(2)
    loop.sampler.stop()
    assert loop.client.reads == 2


def test_an_idle_rate_above_the_control_rate_is_refused_in_one_sentence():
    with pytest.raises(ValueError, match=r"^idle_rate 200 Hz is above control_rate 100 Hz: "
                                         r".*lower idle_rate \(e\.g\. 10\)\.$"):
        Loop(idle_period_s=0.005, period_s=0.01)


def test_after_a_goal_it_samples_fast_until_the_fingers_rest():
    """A cancel's stop decelerates after the goal answered: ~/joint_states shows the rest
    at the control rate, then the loop idles."""
    loop = Loop()
    loop.sampler.start()
    loop.wait_for(1)
    with loop.sampler.busy():
        loop.client.moving = True
        loop.wait_for(3)
    loop.wait_for(len(loop.polls) + 20)  # after the goal: an hour's idle would not get here
    loop.client.moving = False
    with loop.sampled:
        assert loop.sampled.wait_for(lambda: not loop.polls[-1].state.moving, PATIENCE_S)
    assert loop.sampler.period_s == 3600.0
    loop.sampler.stop()
