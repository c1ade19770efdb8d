"""The mock bench with a module array, in its own process: the stage and gauge read over ROS,
the ADC's frames from its pseudo-terminal with the real reader, all checked against the
array world built here from the same parameters (noise off, so the counts are the world's
voltages quantised)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rclpy
import yaml
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from waiting import wait_until, wait_while_advancing

from tactile_sensor.configurations import config_dir
from tactile_sensor.hardware.adc_reader import AdcStreamReader
from tactile_sensor.nodes.background_spin import BackgroundSpin
from tactile_sensor.nodes.ros_session import ros_session
from tactile_sensor.physics.params import PhysicsParams
from tactile_sensor.physics.viscoelastic import RateDependentForce
from tactile_sensor.sim.array_world import ArrayBenchWorld, ArraySkin
from tactile_sensor.sim.profiles import array_profile

CONFIG = config_dir()
FACES = "front,back,left,right"
LSB_V = 5.0 / 4095
# a short shear run: 0.5 s rest, 0.5 s press to 2 mm, 4 directions x 2 s, release, rest
PROTOCOL = {"protocol.name": "shear", "protocol.depth": 0.002, "protocol.speeds": [0.004],
            "protocol.shear": 0.004, "protocol.shear_directions": 4, "protocol.cycles": 1,
            "protocol.hold": 0.0, "protocol.rest": 0.5}
# Upper bound of every wait on a condition: generous, because a wait ends as soon as its
# condition holds and a busy machine may be slow to get there (never a fixed sleep).
PATIENCE_S = 60.0


def overrides(tmp_path: Path, node: str, **values: object) -> str:
    path = tmp_path / f"{node}_overrides.yaml"
    path.write_text(yaml.safe_dump({f"/**/{node}": {"ros__parameters": values}}))
    return str(path)


def start_bench(spawn, tmp_path: Path, **values: object):
    adc = tmp_path / "adc"
    node = spawn("--ros-args", "-r", "__node:=bench",
                 "--params-file", str(CONFIG / "physics.yaml"),
                 "--params-file", str(CONFIG / "bench.yaml"),
                 "--params-file", overrides(tmp_path, "bench", adc_link=str(adc), seed=1,
                                            **{"noise.white": 0.0, "noise.drift": 0.0,
                                               "protocol.start_delay": -1.0, **values}),
                 module="tactile_sensor.nodes.mock_hardware")
    return node, adc


class Listener:
    """Stage and gauge over ROS; starts the protocol with ~/start."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("mock_array_test")
        self.stage: list[tuple[float, list[str], list[float]]] = []
        self.gauge: list[tuple[float, tuple[float, float, float]]] = []
        self.node.create_subscription(JointState, "/bench/stage/joint_states", lambda m:
                                      self.stage.append((_stamp(m), list(m.name),
                                                         list(m.position))), 10000)
        self.node.create_subscription(WrenchStamped, "/bench/gauge/wrench", lambda m:
                                      self.gauge.append((_stamp(m), (m.wrench.force.x,
                                                                     m.wrench.force.y,
                                                                     m.wrench.force.z))),
                                      10000)
        self.start = self.node.create_client(Trigger, "/bench/start")
        self.executor = rclpy.executors.SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.spin = BackgroundSpin(self.executor)

    def start_protocol(self) -> None:
        assert self.start.wait_for_service(timeout_sec=PATIENCE_S)
        # subscribed and hearing before the run starts
        assert wait_until(lambda: self.stage and self.gauge)
        future = self.start.call_async(Trigger.Request())
        assert wait_until(future.done), "no answer from ~/start"
        assert future.result().success

    def streamed_past(self, end_s: float) -> bool:
        """Stage and gauge both published a sample stamped ``end_s`` [s] or later."""
        return bool(self.stage and self.gauge and self.stage[-1][0] >= end_s
                    and self.gauge[-1][0] >= end_s)

    def received(self) -> tuple[int, int]:
        """How much of stage and gauge has come: a starved listener's progress."""
        return len(self.stage), len(self.gauge)

    def first_press_s(self) -> float | None:
        """Stamp of the first stage sample that indents (0.5 s rest after the start)."""
        return next((stamp for stamp, _, p in list(self.stage) if p[0] > 0), None)

    def close(self) -> None:
        self.spin.stop()
        self.node.destroy_node()


def adc_streamed_past(samples: list, after_press_s: float) -> bool:
    """The ADC delivered a sample ``after_press_s`` [s] of device time after its first
    sample that differs from the rest counts."""
    snapshot = list(samples)
    if not snapshot:
        return False
    rest = snapshot[0].counts
    press = next((s for s in snapshot if list(s.counts) != list(rest)), None)
    return press is not None and (
        snapshot[-1].device_time_us - press.device_time_us >= after_press_s * 1e6)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _envelope(world: ArrayBenchWorld, what: str, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """The world's values at t and how much they change within +-2 ms (the time base of
    the messages is known to 1 ms: the first sample after the first rest)."""
    f = getattr(world, what)
    around = np.stack([f(t + dt) for dt in (-0.002, -0.001, 0.0, 0.001, 0.002)])
    return around[2], around.max(axis=0) - around.min(axis=0)


@pytest.fixture(scope="module")
def world() -> ArrayBenchWorld:
    params = PhysicsParams(modules=FACES)
    profile = array_profile(depth_m=0.002, speeds_m_s=(0.004,), rest_s=0.5, shear_m=0.004,
                            shear_directions=4)
    return ArrayBenchWorld(profile, ArraySkin.from_params(params),
                           RateDependentForce.from_params(params),
                           output_play_m=params.output_play)


def test_array_bench_streams_four_channels_and_three_axes(spawn, ros_domain, tmp_path,
                                                          world):
    bench, adc = start_bench(spawn, tmp_path, modules=FACES, **PROTOCOL)
    assert bench.wait_for_output("mock bench ready", 300), bench.output()
    assert "4 channels: front, back, left, right" in bench.output()
    samples: list = []
    with ros_session(), AdcStreamReader(str(adc), samples.append, channels=4):
        listener = Listener()
        try:
            listener.start_protocol()
            # the stage and gauge stamp protocol time: wait until they reached its end
            assert wait_until(lambda: listener.first_press_s() is not None)
            end_s = listener.first_press_s() - 0.5 + world.duration_s
            assert wait_while_advancing(lambda: listener.streamed_past(end_s),
                                        listener.received)
            # and the ADC, on its own clock: until its samples span the protocol (noise
            # off: every sample before the press has the rest counts)
            assert wait_while_advancing(
                lambda: adc_streamed_past(samples, world.duration_s - 0.5), samples.__len__)
        finally:
            listener.close()
    assert "protocol 'shear' started (10.0 s)" in bench.output()

    # stage: three joints; the time base from the first sample that presses
    names = {tuple(n) for _, n, _ in listener.stage}
    assert names == {("stage_z", "stage_x", "stage_y")}
    stamps = np.array([s for s, _, _ in listener.stage])
    positions = np.array([p for _, _, p in listener.stage])
    first = stamps[np.argmax(positions[:, 0] > 0)]
    t = stamps - first + 0.5
    run = (t > 0.6) & (t < world.duration_s - 0.1)
    expected, spread = _envelope(world, "stage_m", t[run])
    excess = np.abs(positions[run] - expected) - spread
    assert excess.max() <= 1e-9, f"stage off the world by {excess.max():.3g} m"
    assert np.abs(positions[:, 1]).max() == pytest.approx(0.004, abs=1e-5)
    assert np.abs(positions[:, 2]).max() == pytest.approx(0.004, abs=1e-5)

    # gauge: (Fx, Fy, Fz) as the world's, rate effect included
    g_stamps = np.array([s for s, _ in listener.gauge])
    forces = np.array([f for _, f in listener.gauge])
    tg = g_stamps - first + 0.5
    run = (tg > 0.6) & (tg < world.duration_s - 0.1)
    expected, spread = _envelope(world, "force_n", tg[run])
    excess = np.abs(forces[run] - expected) - spread
    assert excess.max() <= 1e-6, f"gauge off the world by {excess.max(axis=0)} N"
    assert forces[:, 0].max() > 0.5 and forces[:, 0].min() < -0.5   # +x and -x
    assert forces[:, 1].max() > 0.5 and forces[:, 1].min() < -0.5   # +y and -y

    # ADC: four channels, every sample the world's voltages quantised (noise off)
    assert len(samples) > 0.8 * 1000 * world.duration_s
    assert {len(s.counts) for s in samples} == {4}
    volts = np.array([s.counts for s in samples], float) * LSB_V
    path = world.photoreflector_voltage(np.arange(0.0, world.duration_s, 0.001))
    for v in volts[::25]:
        assert np.abs(path - v).max(axis=1).min() <= 1.0 * LSB_V
    # the sweep reached the +x extreme: right (channel 3) far above left (2) in output
    lr = volts[:, 2] - volts[:, 3]
    assert lr.max() == pytest.approx((path[:, 2] - path[:, 3]).max(), abs=2 * LSB_V)
    assert lr.max() > 0.1


def test_single_module_bench_keeps_its_signal_and_adds_the_lateral_axes(spawn, ros_domain,
                                                                        tmp_path):
    bench, adc = start_bench(spawn, tmp_path, **{"protocol.rest": 0.2})
    assert bench.wait_for_output("mock bench ready", 300), bench.output()
    samples: list = []
    with ros_session(), AdcStreamReader(str(adc), samples.append):
        listener = Listener()
        try:
            listener.start_protocol()
            # until the press is deep and the force high (the protocol reaches both)
            assert wait_while_advancing(
                lambda: max(p[0] for _, _, p in list(listener.stage)) > 0.002
                and max(f[2] for _, f in list(listener.gauge)) > 3.0 and samples,
                listener.received)
        finally:
            listener.close()
    assert {len(s.counts) for s in samples} == {1}
    positions = np.array([p for _, _, p in listener.stage])
    forces = np.array([f for _, f in listener.gauge])
    assert {tuple(n) for _, n, _ in listener.stage} == {("stage_z", "stage_x", "stage_y")}
    assert positions[:, 0].max() > 0.002 and np.all(positions[:, 1:] == 0.0)
    assert forces[:, 2].max() > 3.0 and np.all(forces[:, :2] == 0.0)


def test_shear_with_one_module_is_refused_naming_the_fix(spawn, ros_domain, tmp_path):
    bench, _ = start_bench(spawn, tmp_path, **{"protocol.shear": 0.003})
    assert bench.proc.wait(timeout=60) == 2
    out = bench.output()
    assert "set the physics parameter modules" in out and "Traceback" not in out


def test_bad_shear_directions_are_refused(spawn, ros_domain, tmp_path):
    bench, _ = start_bench(spawn, tmp_path, modules=FACES,
                           **{**PROTOCOL, "protocol.shear_directions": 6})
    assert bench.proc.wait(timeout=60) == 2
    assert "protocol.shear_directions" in bench.output()
