"""``millctl limits --plot --live``: the running service's operating point on the envelope figure."""

from __future__ import annotations

from tests.support.service import Service, run_millctl, wait_for


def test_plot_live_reads_the_running_mill(service: Service) -> None:
    with service.client() as mill, mill.control():
        mill.arm()
        mill.set_speeds(60.0, 300.0)
        wait_for(lambda: (mill.status().measured_vibration_rpm or 0.0) > 100.0, 30.0, "the vibration drive moving")
    out = service.config.parent / "live.png"
    result = run_millctl(service.config, "limits", "--plot", str(out), "--live", "--vib-rpm", "300")
    assert result.returncode == 0, result.stderr
    assert out.read_bytes()[:4] == b"\x89PNG" and f"wrote {out}" in result.stderr
    assert result.stderr.count("307.8 rpm") == 1
