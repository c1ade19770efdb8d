"""The shortest run of ``benchmarks/soak.py`` that holds every fault once (60 s): both
configurations in real processes on the mock devices, grasps throughout; the goals
asserted from its JSON. Longer runs (the default 5 minutes) judge memory growth."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SOAK = Path(__file__).resolve().parents[3] / "benchmarks" / "soak.py"
KINDS = {"adc_unplug", "servo_overload", "cpu_burner", "model_restart", "recording_split"}


@pytest.mark.ros
@pytest.mark.slow
def test_a_soak_with_every_fault_once_meets_the_goals(spawn, ros_domain, tmp_path: Path
                                                    ) -> None:
    report_path = tmp_path / "soak.json"
    # 1 min: 10 s warm-up, the four scheduled faults at least 10 s apart, 10 s to recover
    # from the last (fault_schedule). --split 30: the bag splits at least once, so the
    # recorder's count crosses files.
    run = spawn(sys.executable, "-u", str(SOAK), "--minutes", "1", "--split", "30",
                "--json", str(report_path), "--keep", str(tmp_path / "work"),
                "--results", str(tmp_path / "results"))
    # The bound is for a starved machine (bring-up alone may take minutes); every step of
    # the benchmark waits for a condition, the run itself is 60 s of faults.
    run.proc.wait(timeout=1200)
    assert report_path.exists(), run.output()
    report = json.loads(report_path.read_text())
    goals = {g["name"]: g for g in report["goals"]}
    loss = report["loss"]
    # Every frame the device sent plugged in is a reading, bar those the pulls explain; the
    # device did pull the cable (or the goal would hold trivially).
    assert report["device"]["unplugs"] >= 1 and report["device"]["frames_unplugged"] > 0
    assert loss["lost_outside"] == 0, (loss, run.output())
    assert loss["published"] > 0.5 * loss["sent"], loss
    # The recorder kept every reading, across the split files.
    assert len(report["bag_files"]) >= 2, report["bag_files"]
    assert report["recorded"] == loss["published"], run.output()
    # Every kind of fault happened, was detected where detectable, and recovered without
    # restarting the affected process (only the model restart fault restarts one).
    assert {f["kind"] for f in report["faults"]} == KINDS
    assert all(f["recovered_after_s"] is not None for f in report["faults"]), report["faults"]
    assert goals["every fault recovered without a restart"]["passed"], run.output()
    # The gripper kept grasping through it all.
    assert report["grasps"]["succeeded"] >= 1, report["grasps"]
    # Every process was sampled at the start and the end. RSS growth is NOT asserted: 60 s
    # leave well under a minute after the warm-up, where a single arena or DDS buffer
    # growth of 0.1 MB reads as 6 MB/h; the 5-minute-plus benchmark judges it. Open file
    # descriptors are discrete, so a leak per reconnection (the ADC was pulled, the model
    # restarted) would show: the bench driver ends with no more than it started with + 2.
    driver = next(p for p in report["processes"] if p["process"].startswith("bench_driver"))
    assert driver["samples"] >= 2 and driver["fds_end"] <= driver["fds_start"] + 2, driver
    # The benchmark's exit status follows the goals.
    assert run.proc.returncode == (0 if all(g["passed"] for g in goals.values()) else 1)
    # The summary's figures went where --results said, for the benchmark page.
    figures = {f["name"]: f for f in json.loads(
        (tmp_path / "results" / "soak.json").read_text())["figures"]}
    assert figures["readings lost outside the unplugged windows"]["value"] == 0
    assert figures["every fault recovered without a restart"]["met"] is True


def test_a_run_too_short_for_every_fault_is_refused_before_anything_starts(
        tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, str(SOAK), "--minutes", "0.5",
                           "--keep", str(tmp_path / "work")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "needs at least" in done.stderr and "--minutes 0.5" in done.stderr
    assert not (tmp_path / "work").exists()


def test_an_existing_keep_folder_is_refused_before_anything_starts(tmp_path: Path) -> None:
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "earlier.log").write_text("another run's\n")
    done = subprocess.run([sys.executable, str(SOAK), "--minutes", "2",
                           "--keep", str(tmp_path / "work")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "already exists; give a new folder" in done.stderr
    assert "Traceback" not in done.stderr
    assert [p.name for p in (tmp_path / "work").iterdir()] == ["earlier.log"]


@pytest.mark.ros
def test_a_node_that_does_not_come_up_is_named_and_everything_stops(
        spawn, ros_domain, own_processes, tmp_path: Path) -> None:
    # 1 ms is less than any recorder needs to subscribe: bring-up fails at its first step
    run = spawn(sys.executable, "-u", str(SOAK), "--minutes", "2", "--bring-up-timeout",
                "0.001", "--keep", str(tmp_path / "work"), "--results", str(tmp_path / "res"))
    assert run.proc.wait(timeout=120) == 1, run.output()
    assert "soak: the recorder did not subscribe" in run.output()
    assert "recorder.log ends" in run.output()
    assert not (tmp_path / "work" / "soak.json").exists()
    assert not (tmp_path / "res").exists()
    assert own_processes() == []  # the nodes it had started are gone with it


def test_a_hung_ros_teardown_after_the_run_keeps_the_figures_and_exits(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture) -> None:
    """On Kilted, Fast DDS can deadlock as the benchmark destroys its own node after a
    complete run. The figures are written before the teardown, and a teardown that does not
    end makes the process exit with the run's status."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("soak_benchmark", SOAK)
    assert spec is not None and spec.loader is not None
    soak = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, soak)  # its dataclasses look it up there
    spec.loader.exec_module(soak)
    events: list[str] = []

    class HungTeardown:
        def __init__(self, *args: object) -> None:
            pass

        def run(self) -> dict:
            return {"goals": [{"name": "g", "passed": False}]}

        def close(self) -> bool:
            events.append("close")
            return False

    class Exited(Exception):
        pass

    def exit_now(code: int) -> None:
        events.append(f"exit {code}")
        raise Exited

    monkeypatch.setattr(soak, "Soak", HungTeardown)
    monkeypatch.setattr(soak, "print_report", lambda report: events.append("report"))
    monkeypatch.setattr(soak, "report_figures", lambda report: [soak.Figure("g", "FAIL")])
    monkeypatch.setattr(soak.os, "_exit", exit_now)
    report_path = tmp_path / "soak.json"
    with pytest.raises(Exited):
        soak.main(["--minutes", "2", "--json", str(report_path), "--keep",
                   str(tmp_path / "work"), "--results", str(tmp_path / "results")])
    assert events == ["report", "close", "exit 1"]  # a failed goal: status 1
    assert json.loads(report_path.read_text())["goals"][0]["passed"] is False
    assert json.loads((tmp_path / "results" / "soak.json").read_text())["figures"][0][
        "value"] == "FAIL"
    assert "ROS teardown did not end" in capsys.readouterr().out


def test_the_summary_figures_take_each_fault_kinds_slowest_and_the_worst_growth(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("soak_benchmark", SOAK)
    assert spec is not None and spec.loader is not None
    soak = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, soak)
    spec.loader.exec_module(soak)
    report = {
        "loss": {"lost_outside": 0, "lost_in_windows": 7, "published": 900},
        "recorded": 900,
        "faults": [{"kind": "adc_unplug", "detected_after_s": 0.5, "recovered_after_s": 2.5},
                   {"kind": "adc_unplug", "detected_after_s": 0.7, "recovered_after_s": 2.0},
                   {"kind": "servo_overload", "detected_after_s": 0.1,
                    "recovered_after_s": None}],
        "processes": [{"process": "bench_driver (pid 1)", "rss_growth_mb_per_h": 0.5},
                      {"process": "gripper (pid 2)", "rss_growth_mb_per_h": float("nan")},
                      {"process": f"{soak.SELF} (pid 3)", "rss_growth_mb_per_h": 40.0}],
        "grasps": {"succeeded": 4, "attempted": 5},
        "goals": [{"name": "no reading lost", "passed": True, "detail": "0 lost"}],
    }
    figures = {f.name: f for f in soak.report_figures(report)}
    assert figures["adc_unplug: slowest detection of 2"].value == 0.7
    assert figures["adc_unplug: slowest recovery of 2"].value == 2.5
    assert figures["servo_overload: slowest recovery of 1"].value is None  # not recovered
    assert figures["worst RSS growth"].value == 0.5  # this process is not judged
    assert figures["no reading lost"].met is True
