"""The same sweep on the local pool, on a local Ray and on a Ray cluster (a head started here
with ``ray start --head``, bound to loopback, stopped at the end) gives the same rows: the
seeds decide the figures, not the engine. Ray is the optional extra ``agvsim[ray]``."""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from agvsim.sweep.folder import read_rows
from agvsim.sweep.runs import TIMING_COLUMNS

ray = pytest.importorskip("ray")

SPEC = "base: {distance: 25, observations: geometric}\ngrid: {odometry: [typical, worn]}\nseeds: 2\n"


def _sweep(spec: Path, out: Path, *extra: str, env: dict | None = None) -> dict:
    p = subprocess.run([sys.executable, "-m", "agvsim", "sweep", str(spec), "--out", str(out), "--workers", "2",
                        "--no-progress", "--no-plots", "--json", *extra], capture_output=True, text=True, timeout=300,
                       env=env)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def _figures(out: Path) -> dict:
    return {k: {c: v for c, v in r.items() if c not in TIMING_COLUMNS} for k, r in read_rows(out).items()}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_local_pool_local_ray_and_a_ray_cluster_give_the_same_rows(tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC)
    pool = _sweep(spec, tmp_path / "pool")
    local_ray = _sweep(spec, tmp_path / "ray", "--engine", "ray")
    assert pool["finished"] == local_ray["finished"] == 4 and local_ray["engine_startup_s"] > 0
    reference = _figures(tmp_path / "pool")
    assert len(reference) == 4 and all(r["status"] == "ok" for r in reference.values())
    assert _figures(tmp_path / "ray") == reference

    port = _free_port()
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # (short: Ray's socket paths must fit in 107 bytes)
    # a loopback test cluster without Ray's token authentication (a client of a head started with
    # it must present the head's token; that is Ray's to set up, not the sweep's)
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "disabled"}
    ray_cli = str(Path(sys.executable).with_name("ray"))  # (the venv's, on PATH or not)
    head = subprocess.Popen([ray_cli, "start", "--head", "--block", "--node-ip-address=127.0.0.1", f"--port={port}",
                             "--num-cpus=2", "--include-dashboard=false", "--disable-usage-stats",
                             f"--temp-dir={temp}"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
                            start_new_session=True, cwd=tmp_path)
    try:
        deadline = time.time() + 90
        while True:  # the head answers on its port
            assert head.poll() is None, head.communicate()[0]
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", port)) == 0:
                    break
            assert time.time() < deadline, "the Ray head did not start"
            time.sleep(0.5)
        cluster = _sweep(spec, tmp_path / "cluster", "--engine", "ray", "--address", f"127.0.0.1:{port}", env=env)
        assert cluster["finished"] == 4
        assert _figures(tmp_path / "cluster") == reference
    finally:
        # Ctrl-C, as in a terminal: the head stops its processes in 2-3 s (on SIGTERM it drains for 30 s)
        if head.poll() is None:
            head.send_signal(signal.SIGINT)
        try:
            head.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        try:
            os.killpg(head.pid, signal.SIGKILL)  # anything of the head's still running
        except ProcessLookupError:
            pass
        head.wait()
        head.stdout.close()
        shutil.rmtree(temp, ignore_errors=True)
