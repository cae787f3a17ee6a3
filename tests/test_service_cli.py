"""``tamp-service``: help, bad arguments, clean shutdown of ``run`` on SIGTERM/SIGINT, and the
demo mission of simple.json through the bus to completion with a recording read back."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from service.cli import main

from .conftest import ROOT, world_file
from .service_helpers import Recorder, client, free_port, unique_prefix, wait_for

ENV = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def _cli(*args, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "service.cli", *args], env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


def test_help_documents_every_option(capsys):
    for sub, extra in (("run", []), ("demo", ["--speed", "--seed", "--json"])):
        with pytest.raises(SystemExit) as info:
            main([sub, "--help"])
        assert info.value.code == 0
        out = capsys.readouterr().out
        for opt in ["--world", "--task", "--robot", "--listen", "--connect", "--zenoh-config", "--record",
                    "--viewer", "--rate", "--duration", "--watchdog", "--accel-max", "--alpha-max", "--unlimited",
                    "--no-crawl-guard", "--fields",
                    *extra]:
            assert opt in out, (sub, opt)


def test_acceleration_limits_set_the_executives_rate_limited_controller():
    """The executive's default controller is rate-limited; ``--accel-max`` / ``--alpha-max``
    change its limits and nothing else, ``--unlimited`` turns the rate limit off."""
    from dataclasses import replace

    from navigation.control import UNLIMITED
    from service.cli import _executive_config, build_parser
    from tamp.executive import ExecutiveConfig

    parse = build_parser().parse_args
    default = ExecutiveConfig().controller
    assert (default.accel_max, default.alpha_max, default.brake_share) == (1.0, 6.0, 0.5)
    assert _executive_config(parse(["run", "--world", "simple"])) is None
    cfg = _executive_config(parse(["demo", "--accel-max", "2"])).controller
    assert cfg == replace(default, accel_max=2.0)
    cfg = _executive_config(parse(["run", "--world", "simple", "--alpha-max", "3"])).controller
    assert cfg == replace(default, alpha_max=3.0)
    cfg = _executive_config(parse(["run", "--world", "simple", "--unlimited"])).controller
    assert cfg == replace(default, **UNLIMITED)


def test_no_crawl_guard_turns_the_executives_guard_off():
    from navigation import CrawlConfig
    from service.cli import _executive_config, build_parser
    from tamp.executive import ExecutiveConfig

    parse = build_parser().parse_args
    cfg = _executive_config(parse(["run", "--world", "simple", "--no-crawl-guard"]))
    assert cfg.crawl_guard is None and cfg.controller == ExecutiveConfig().controller
    both = _executive_config(parse(["demo", "--no-crawl-guard", "--accel-max", "2"]))
    assert both.crawl_guard is None and both.controller.accel_max == 2.0
    assert _executive_config(parse(["demo", "--accel-max", "2"])).crawl_guard == CrawlConfig()


def test_fields_tracks_each_waypoints_field_instead_of_pursuing_the_path():
    from service.cli import _executive_config, build_parser
    from tamp.executive import ExecutiveConfig

    parse = build_parser().parse_args
    assert ExecutiveConfig().pursuit == 0.3
    cfg = _executive_config(parse(["run", "--world", "simple", "--fields"]))
    assert cfg.pursuit == 0.0 and cfg == ExecutiveConfig(pursuit=0.0)
    both = _executive_config(parse(["demo", "--fields", "--no-crawl-guard"]))
    assert both.pursuit == 0.0 and both.crawl_guard is None


@pytest.mark.parametrize("argv, needle", [
    (["run", "--accel-max", "-1"], "--accel-max"), (["demo", "--seed", "-1"], "--seed"),
    (["run", "--rate", "0"], "--rate"), (["demo", "--speed", "fast"], "--speed"), (["jump"], "invalid choice"),
    (["run"], "--world"), (["run", "--world", "no/such/world.json"], "no/such"),
    (["run", "--world", "simple", "--task", "F (a"], "parse_error"),
    (["run", "--world", "simple", "--zenoh-config", "/no/such.json5"], "--zenoh-config"),
    # Rerun sinks: a traceback before (and a viewer name without a port streamed to port 80)
    (["run", "--world", "simple", "--record", "/no/such/dir/x.rrd"], "/no/such/dir/x.rrd"),
    (["demo", "--world", "simple", "--record", "/no/such/dir/x.rrd"], "cannot record"),
    (["demo", "--viewer", "notanaddress"], "HOST:PORT"), (["run", "--viewer", "host:99999"], "HOST:PORT"),
    (["demo", "--viewer", "garbage://x"], "rerun+http://"),
    (["demo", "--serve", "localhost:9876"], "IP:PORT"), (["run", "--serve", "70000"], "IP:PORT"),
    (["demo", "--world", "simple", "--serve", str(free_port()), "--serve-memory", "lots"], "server_memory_limit"),
])
def test_bad_arguments_give_one_error_line_and_exit_2(argv, needle, capsys):
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_run_stops_cleanly_on_signal(sig):
    port = free_port()
    prefix = unique_prefix("cli")
    proc = _cli("run", "--world", str(world_file("simple")), "--prefix", prefix,
                "--listen", f"tcp/127.0.0.1:{port}")
    cl = client(f"tcp/127.0.0.1:{port}")
    try:
        assert wait_for(lambda: any(r.ok for r in cl.liveliness().get(f"{prefix}/alive", timeout=1.0)), 20.0)
        cmd = Recorder(cl, f"{prefix}/cmd_vel")
        status = Recorder(cl, f"{prefix}/status")
        assert wait_for(lambda: cmd.last is not None, 5.0)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=15)
        assert proc.returncode == 0, err
        assert "Traceback" not in err
        assert cmd.last["v"] == 0.0 and cmd.last["omega"] == 0.0
        assert wait_for(lambda: status.last and status.last["message"] == "service stopped", 2.0)
        assert wait_for(lambda: not any(r.ok for r in cl.liveliness().get(f"{prefix}/alive", timeout=1.0)), 5.0)
        with socket.socket() as s:  # no listener left on the port (TIME_WAIT pairs are allowed)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind(("127.0.0.1", port))
            s.listen()
        cmd.close()
        status.close()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        cl.close()


def test_demo_keep_going_patrols_until_the_duration():
    """``--keep-going``: a recurrent mission completes after one round of its cycle, and the demo
    keeps the robot patrolling until ``--duration`` (its summary counts the arrivals)."""
    proc = _cli("demo", "--world", str(world_file("simple")), "--task", "G F a & G F b", "--speed", "8",
                "--keep-going", "--duration", "60", "--json", "--prefix", unique_prefix("patrol"))
    out, err = proc.communicate(timeout=150)
    assert proc.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["completed"] is True and summary["collisions"] == 0, (summary, err)
    assert summary["sim_time"] >= 59.0 and summary["accepting_visits"] >= 3, summary
    assert {"a", "b"} <= set(summary["visited"][-4:]), summary["visited"]


def test_demo_over_points_messages_completes_and_maps_the_obstacles():
    """``demo --points``: the simulator publishes ``points`` instead of ``scan`` and the mission
    completes on them over the bus (points messages were dropped by the brain until the
    forty-eighth session, and the demo waited 60 s for a scan that never came)."""
    proc = _cli("demo", "--world", str(world_file("simple")), "--speed", "4", "--points", "--json",
                "--duration", "120", "--prefix", unique_prefix("points"))
    out, err = proc.communicate(timeout=150)
    assert proc.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["completed"] is True and summary["collisions"] == 0, (summary, err)
    assert summary["sim_time"] < 60.0 and summary["warnings"] == 0, summary
    assert "input dropped" not in err


def test_demo_mission_of_simple_completes_over_the_bus_with_a_recording(tmp_path):
    rrd = tmp_path / "demo.rrd"
    proc = _cli("demo", "--world", str(world_file("simple")), "--speed", "4", "--record", str(rrd), "--json",
                "--duration", "120", "--prefix", unique_prefix("demo"))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["completed"] is True, (summary, err)
    assert summary["collisions"] == 0
    assert summary["visited"][:2] in (["a", "b"], ["b", "a"])
    # the demo waits for its simulator's first pose and scan: no watchdog stop at the start
    states = [line.split("] ", 1)[1].split()[0] for line in err.splitlines() if line.startswith("[") and "] " in line]
    assert states and "blocked" not in states, err
    # the recording verifies and holds the expected entities
    rerun = Path(sys.executable).parent / "rerun"
    verify = subprocess.run([str(rerun) if rerun.exists() else "rerun", "rrd", "verify", str(rrd)],
                            capture_output=True, text=True, timeout=60)
    assert verify.returncode == 0, verify.stderr
    from rerun.chunk import RrdReader

    paths = {str(c.entity_path) for c in RrdReader(str(rrd)).stream().collect().stream()}
    for p in ("/world/workspace", "/world/regions", "/world/obstacles/true", "/world/obstacles/estimated",
              "/world/lidar", "/world/robot", "/world/robot/trail", "/world/path", "/world/path/vertices",
              "/world/goal", "/world/nf", "/world/field", "/plots/v", "/plots/omega", "/plots/tick_ms",
              "/status/state", "/status/plan"):
        assert p in paths, (p, sorted(paths))


def test_a_viewer_that_never_answers_costs_an_error_line_not_the_run(caplog):
    from service.viz import Telemetry

    class Stream:  # a RecordingStream whose gRPC sink never connected
        disconnected = False

        def flush(self, timeout_sec=None):
            raise RuntimeError("Flush timed out - not all log messages were sent")

        def disconnect(self):
            self.disconnected = True

    stream = Stream()
    tel = Telemetry(stream)
    with caplog.at_level("ERROR", logger="service.viz"):
        tel.close()
    assert stream.disconnected and not tel.enabled
    assert "not every message reached" in caplog.text


def test_serve_hosts_a_rerun_server_that_a_late_viewer_reads_from_the_start(tmp_path):
    """``--serve PORT``: the service hosts Rerun's gRPC server; a client that connects after the
    start (here ``rerun URL --save``, the viewer's headless form) receives everything from the
    start (the static workspace too) and the mission's live data."""
    port = free_port()
    proc = _cli("demo", "--world", str(world_file("simple")), "--speed", "4", "--serve", str(port), "--json",
                "--duration", "120", "--prefix", unique_prefix("serve"))
    try:
        assert wait_for(lambda: _port_open(port), timeout=60), "the Rerun server never listened"
        rerun = Path(sys.executable).parent / "rerun"
        rrd = tmp_path / "served.rrd"
        viewer = subprocess.run([str(rerun) if rerun.exists() else "rerun", f"rerun+http://127.0.0.1:{port}/proxy",
                                 "--save", str(rrd), "--port", str(free_port())],
                                capture_output=True, text=True, timeout=150)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "rerun --connect rerun+http://127.0.0.1:" in err
    assert json.loads(out.strip().splitlines()[-1])["completed"] is True
    assert viewer.returncode == 0, viewer.stderr
    from rerun.chunk import RrdReader

    paths = {str(c.entity_path) for c in RrdReader(str(rrd)).stream().collect().stream()}
    for p in ("/world/workspace", "/world/obstacles/true", "/world/robot", "/world/lidar", "/status/state"):
        assert p in paths, (p, sorted(paths))


def _port_open(port: int) -> bool:
    try:
        socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
        return True
    except OSError:
        return False


def test_a_world_with_more_regions_than_a_map_holds_is_one_error_line(tmp_path, capsys):
    from tamp.navmap import MAX_REGIONS

    data = json.loads(world_file("simple").read_text())
    data["workspace"] = {"center": [10, 10], "width": 20, "height": 20, "theta": 0, "s": 0.99}
    data["obstacles"], data["known_obstacles"] = [], []
    data["regions"] = {f"q{i}": {"center": [3 + (i % 11) * 1.4, 3 + (i // 11) * 1.4], "radius": 0.1}
                       for i in range(MAX_REGIONS + 1)}
    data["robot"]["start"] = [10.0, 1.5, 0.0]
    data["task"] = "F q0"
    data.pop("events", None)
    path = tmp_path / "crowded.json"
    path.write_text(json.dumps(data))
    assert main(["run", "--world", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{MAX_REGIONS + 1} regions" in err and "--task" not in err, err
