"""benchmarks/results.py and benchmarks/report.py: figures written as JSON come back on the
generated page with their command, commit, machine and date; a bad file is one sentence."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

# The scripts in benchmarks/ import each other by file name, as `python benchmarks/x.py` does.
BENCHMARKS = Path(__file__).resolve().parents[3] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
report = importlib.import_module("report")
results = importlib.import_module("results")
Figure, ResultsError = results.Figure, results.ResultsError
read_results, write_results = results.read_results, results.write_results


@pytest.fixture(autouse=True)
def measured_at_a_commit(monkeypatch: pytest.MonkeyPatch) -> None:
    """The figures these tests write count as measured at a clean commit, as in CI, also
    while the checkout has uncommitted changes."""
    monkeypatch.setattr(results, "STARTED_ON", "0123abc")


def write_two(folder: Path) -> None:
    write_results("fem", [Figure("default sweep", 1.234567, "s", "<= 2 s", True),
                          Figure("force at 3 mm", 7.1, "N"),
                          Figure("written", 110403.2, "messages/s")],
                  argv=["benchmarks/bench_fem.py", "--no-study"], directory=folder,
                  notes="load average 0.3")
    write_results("adc", [Figure("highest ingest rate", 40000, "frames/s", ">= 5000", False),
                          Figure("lag | pipe", float("nan"), "ms")],
                  argv=["benchmarks/bench_adc.py"], directory=folder)


def test_page_holds_every_figure_with_command_commit_machine_and_date(tmp_path, capsys):
    results, out = tmp_path / "results", tmp_path / "docs" / "benchmarks.md"
    write_two(results)
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    for name in ("bench_adc.py", "bench_fem.py", "bench_model.py"):
        (scripts / name).write_text("")
    (out.parent / "benchmarks").mkdir(parents=True)
    (out.parent / "benchmarks" / "gone.md").write_text(report.MARKER)  # no longer published
    assert report.main(["--results", str(results), "--out", str(out),
                        "--benchmarks", str(scripts)]) == 0
    page = out.read_text()
    assert "make bench-report" in page and "generated" in page.lower()
    assert "_generated/benchmarks.md" in page  # the figures drawn from the results
    assert "| [adc](benchmarks/adc.md) | 0 / 1 **NOT all met** | 2 |" in page
    assert "| [fem](benchmarks/fem.md) | 1 / 1 | 3 |" in page
    assert "`bench_model.py`" in page.split("| benchmark |")[0]  # listed as not measured
    assert "bench_fem.py`" not in page.split("Not measured")[1].split("| benchmark |")[0]
    assert not (out.parent / "benchmarks" / "gone.md").exists()
    fem = (out.parent / "benchmarks" / "fem.md").read_text()
    assert fem.startswith("# fem\n")
    assert "`python benchmarks/bench_fem.py --no-study`" in fem
    assert "| default sweep | 1.235 s | <= 2 s: met |" in fem
    assert "| force at 3 mm | 7.1 N |  |" in fem
    assert "| written | 110,403 messages/s |  |" in fem
    assert "load average 0.3" in fem
    record = json.loads((results / "fem.json").read_text())
    assert f"commit `{record['commit']}`" in fem
    assert record["date"] in fem
    assert f"{record['machine']['cores']} cores, {record['machine']['cpu_model']}" in fem
    adc = (out.parent / "benchmarks" / "adc.md").read_text()
    assert "| highest ingest rate | 40,000 frames/s | >= 5000: NOT met |" in adc
    assert "| lag \\| pipe | n/a |  |" in adc  # NaN is stored as null, shown as n/a
    assert page.index("[adc]") < page.index("[fem]")


def test_write_results_names_the_script_relative_to_the_repository(tmp_path):
    path = write_results("x", [Figure("n", 3)],
                         argv=[str(BENCHMARKS / "bench_fem.py"), "--quick"],
                         directory=tmp_path)
    record = read_results(path)
    assert record["command"] == "python benchmarks/bench_fem.py --quick"
    assert record["figures"] == [{"name": "n", "value": 3, "unit": "", "goal": "",
                                  "met": None}]
    assert record["machine"]["cores"] >= 1


@pytest.mark.parametrize(("content", "says"), [
    ("{not json", "is not valid JSON (line 1"),
    ("[1, 2]", "holds a JSON list, not a benchmark result"),
    ('{"benchmark": "x", "command": "python b.py", "commit": "abc", "date": "d", '
     '"machine": {}}', "lacks the list field 'figures'"),
    ('{"benchmark": "x", "command": "python b.py", "commit": "abc", "date": "d", '
     '"machine": {}, "figures": [{"value": 1}]}', "figure 1 has no 'name' and 'value'"),
])
def test_a_bad_results_file_is_one_sentence_naming_it_and_the_fix(tmp_path, capsys, content,
                                                                   says):
    results = tmp_path / "results"
    write_two(results)
    bad = results / "broken.json"
    bad.write_text(content)
    out = tmp_path / "benchmarks.md"
    assert report.main(["--results", str(results), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err
    assert str(bad) in err and "rerun the benchmark that writes it or delete" in err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()
    with pytest.raises(ResultsError, match="rerun the benchmark"):
        read_results(bad)


def test_a_missing_results_folder_says_to_run_the_benchmarks(tmp_path, capsys):
    assert report.main(["--results", str(tmp_path / "none"),
                        "--out", str(tmp_path / "b.md")]) == 2
    err = capsys.readouterr().err.strip()
    assert "run `make bench`" in err and len(err.splitlines()) == 1


def test_the_committed_page_is_what_the_committed_results_render():
    """docs/benchmarks.md is generated: a hand edit, or a results file added without
    `make bench-report`, shows here."""
    records = report.load(report.RESULTS)
    stale = "differs from what benchmarks/results renders: run `make bench-report` and commit"
    assert report.OUT.read_text() == report.render(
        records, report.benchmark_scripts(report.BENCHMARKS)), f"docs/benchmarks.md {stale}"
    folder = report.OUT.with_suffix("")
    pages = report.render_pages(records)
    assert {p.stem for p in folder.glob("*.md")} == set(pages), f"docs/benchmarks/ {stale}"
    for name, text in pages.items():
        assert (folder / f"{name}.md").read_text() == text, f"docs/benchmarks/{name}.md {stale}"


def test_a_benchmark_that_needs_ros2_says_so_and_is_skipped_not_failed(monkeypatch, capsys):
    import shutil

    monkeypatch.setattr(shutil, "which", lambda name: None)
    assert results.without_ros2("bench_x", " (or use bench_y)") == results.CANNOT_RUN_HERE == 77
    said = capsys.readouterr().err.strip()
    assert said.count(".") == 1 and "bench_x needs `ros2 launch`" in said and "bench_y" in said
    monkeypatch.setattr(shutil, "which", lambda name: f"/usr/bin/{name}")
    assert results.without_ros2("bench_x") is None
