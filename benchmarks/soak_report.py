"""What a soak prints at its end: the summary for a reader, every count, fault and process
with the goals' verdicts."""

from __future__ import annotations

from typing import Any

from soak_processes import SAMPLE_PERIOD_S, say
from soak_run import FaultResult, fault_line


def print_report(r: dict[str, Any]) -> None:
    d, loss = r["device"], r["loss"]
    say(f"\nsoak {r['minutes']:g} min at {r['adc_rate_hz']:g} Hz (bring-up "
        f"{r['bring_up_s']:.1f} s)")
    say(f"bench ADC: {d['frames_generated']:,} frames generated, {d['frames_unplugged']:,} "
        f"while unplugged ({d['unplugs']} pulls), {loss['sent']:,} sent plugged in, "
        f"{d['bytes_lost']:,} bytes lost to a full host buffer")
    b = r["bench_driver"]
    say(f"bench driver: {int(b['frames']):,} frames received, {b['frames_dropped']} missing "
        f"in the sequence, {b['frames_overflowed']} overflowed, {b['reconnections']} "
        f"connections; {loss['published']:,} readings published")
    say(f"readings lost: {loss['lost_total']:,} = {loss['lost_in_windows']:,} in the "
        f"unplugged windows + {loss['lost_outside']:,} outside")
    g = r["gripper_driver"]
    if g:
        say(f"gripper driver: {int(g.get('frames', 0)):,} frames, "
            f"{g.get('frames_dropped')} missing, {g.get('frames_overflowed')} overflowed, "
            f"{int(g.get('readings_published', 0)):,} readings published (while heard)")
    say(f"recorder: {r['recorded']:,} readings in {len(r['bag_files'])} file(s) "
        f"({', '.join(r['bag_files'])}) of {loss['published']:,} published")
    say("faults (at: since the benchmark started; detection and recovery: from the "
        "injection, for a split from when it was due):")
    for f in r["faults"]:
        say(f"  {f['at_s']:6.1f} s {f['kind']:<16} " + fault_line(FaultResult(**f)))
    say(f"processes (RSS growth: Theil-Sen slope of samples every {SAMPLE_PERIOD_S:g} s "
        f"from {r['rss_warmup_s']:.0f} s after each process's first one; this process "
        "keeps every report, so it is listed but not judged):")
    say(f"  {'process':<34} {'RSS MB start':>12} {'end':>7} {'MB/h':>8} {'fds':>9} {'fd/h':>7}")
    for p in r["processes"]:
        say(f"  {p['process']:<34} {p['rss_start_mb']:12.1f} {p['rss_end_mb']:7.1f} "
            f"{p['rss_growth_mb_per_h']:+8.2f} {p['fds_start']:>4}->{p['fds_end']:<4} "
            f"{p['fd_growth_per_h']:+7.1f}")
    gr = r["grasps"]
    say(f"grasps: {gr['succeeded']} of {gr['attempted']} succeeded ({gr['outcomes']})")
    say(f"exit codes: {r['exit_codes']}")
    for goal in r["goals"]:
        say(f"{'PASS' if goal['passed'] else 'FAIL'}  {goal['name']}: {goal['detail']}")
