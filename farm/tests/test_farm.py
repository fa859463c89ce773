"""pathtracer-farm end to end on loopback Dask clusters, against the release binary.

Every wait is bounded; every assertion is about bytes, exit codes and messages, never time.
The binary is ``$PATHTRACER_BIN`` or ``target/release/pathtracer`` of this repository.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BINARY = Path(os.environ.get("PATHTRACER_BIN", REPO / "target" / "release" / "pathtracer"))
FLAGS = ["-s", "8", "-m", "3", "-r", "64", "48"]
TIMEOUT = 180  # seconds: the most any one command may take


def launcher():
    script = Path(sys.executable).parent / "pathtracer-farm"
    return [str(script)] if script.exists() else [sys.executable, "-m", "pathtracer_farm.cli"]


def farm(*args, env=None, timeout=TIMEOUT):
    cmd = launcher() + ["render", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)


@pytest.fixture(scope="session")
def binary():
    assert BINARY.is_file(), f"{BINARY} missing: run cargo build --release first"
    return BINARY


@pytest.fixture(scope="session")
def scene(binary, tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "cornell.dae"
    subprocess.run([binary, "gen", "cornell", "-o", path], check=True, capture_output=True, timeout=60)
    return path


def whole(binary, scene, out, flags=FLAGS):
    subprocess.run([binary, *flags, "--quiet", "-f", out, scene], check=True, capture_output=True,
                   timeout=TIMEOUT)
    return Path(out).read_bytes()


def ok(proc):
    assert proc.returncode == 0, f"exit {proc.returncode}\nstdout: {proc.stdout}\nstderr: {proc.stderr}"
    assert "Traceback" not in proc.stderr, proc.stderr
    return proc


def one_line_error(proc, want):
    assert proc.returncode == 2, f"exit {proc.returncode}: {proc.stderr}"
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and want in errors[0], proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == errors[0], proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def slow_binary(tmp_path, binary, delay):
    """A wrapper that notes each part it starts (marks/starts, marks/pid-PID), waits, then runs
    the renderer in its own process (exec keeps the PID)."""
    marks = tmp_path / "marks"
    marks.mkdir()
    wrapper = tmp_path / "pathtracer-slow"
    wrapper.write_text(
        "#!/bin/sh\n"
        'case " $* " in\n'
        '  *" --info "*) ;;\n'
        f'  *" --part "*) echo $$ >> "{marks}/starts"; touch "{marks}/pid-$$"; sleep {delay} ;;\n'
        "esac\n"
        f'exec "{binary}" "$@"\n'
    )
    wrapper.chmod(0o755)
    return wrapper, marks


def starts(marks):
    path = marks / "starts"
    return len(path.read_text().split()) if path.exists() else 0


def wait_for(predicate, what, limit=90):
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        result = predicate()
        if result:
            return result
        time.sleep(0.05)
    raise AssertionError(f"timed out after {limit} s waiting for {what}")


def first_pid(marks):
    pids = sorted(marks.glob("pid-*"), key=lambda p: p.stat().st_mtime)
    return int(pids[0].name[4:]) if pids else None


def parent_of(pid):
    with open(f"/proc/{pid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[1])


def test_two_workers_give_the_bytes_of_one_render(binary, scene, tmp_path):
    want = whole(binary, scene, tmp_path / "whole.png")
    proc = ok(farm(scene, "-f", tmp_path / "farm.png", "--parts", 6, "--workers", 2, "--binary", binary, *FLAGS))
    assert (tmp_path / "farm.png").read_bytes() == want
    assert "Merged 6 parts" in proc.stdout and "BVH traced" in proc.stdout
    assert "6/6" in proc.stderr
    want_exr = whole(binary, scene, tmp_path / "whole.exr", FLAGS + ["--shading", "mis", "--seed", "5"])
    ok(farm(scene, "-f", tmp_path / "farm.exr", "--parts", 3, "--workers", 2, "--binary", binary,
            *FLAGS, "--shading", "mis", "--seed", "5"))
    assert (tmp_path / "farm.exr").read_bytes() == want_exr


def test_several_scenes_are_frames_of_one_job(binary, scene, tmp_path):
    second = tmp_path / "second.dae"
    second.write_text(scene.read_text() + "\n")
    frames = tmp_path / "frames"
    frames.mkdir()
    ok(farm(scene, second, "-f", frames / "{name}.png", "--parts", 2, "--workers", 2, "--binary", binary, *FLAGS))
    assert (frames / "cornell.png").read_bytes() == whole(binary, scene, tmp_path / "a.png")
    assert (frames / "second.png").read_bytes() == whole(binary, second, tmp_path / "b.png")
    one_line_error(farm(scene, second, "-f", tmp_path / "x.png", "--parts", 2, "--binary", binary), "{name}")


def run_and_kill(binary, scene, tmp_path, kill):
    """Starts a 2-worker job of slow parts, kills something once the first part runs, and
    returns the finished job's process."""
    wrapper, marks = slow_binary(tmp_path, binary, delay=1)
    out = tmp_path / "farm.png"
    cmd = launcher() + ["render", str(scene), "-f", str(out), "--parts", "4", "--workers", "2",
                        "--binary", str(wrapper), *FLAGS]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        pid = wait_for(lambda: first_pid(marks), "the first part to start")
        kill(pid)
        stdout, stderr = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    return subprocess.CompletedProcess(cmd, proc.returncode, stdout, stderr), marks


def test_a_killed_worker_is_retried_with_the_same_bytes(binary, scene, tmp_path):
    want = whole(binary, scene, tmp_path / "whole.png")
    proc, marks = run_and_kill(binary, scene, tmp_path, lambda pid: os.kill(parent_of(pid), signal.SIGKILL))
    ok(proc)
    assert (tmp_path / "farm.png").read_bytes() == want
    assert starts(marks) >= 5
    assert "retried" in proc.stderr, proc.stderr


def test_a_killed_renderer_is_retried_with_the_same_bytes(binary, scene, tmp_path):
    want = whole(binary, scene, tmp_path / "whole.png")
    proc, marks = run_and_kill(binary, scene, tmp_path, lambda pid: os.kill(pid, signal.SIGKILL))
    ok(proc)
    assert (tmp_path / "farm.png").read_bytes() == want
    assert starts(marks) == 5
    assert "retried" in proc.stderr, proc.stderr


def test_an_interrupted_job_resumes_without_rendering_finished_parts(binary, scene, tmp_path):
    want = whole(binary, scene, tmp_path / "whole.png")
    wrapper, marks = slow_binary(tmp_path, binary, delay=0.5)
    out = tmp_path / "farm.png"
    parts = tmp_path / "farm.png.parts"
    cmd = launcher() + ["render", str(scene), "-f", str(out), "--parts", "4", "--workers", "1",
                        "--binary", str(wrapper), *FLAGS]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_for(lambda: list(parts.glob("part-*.ptpart")), "a finished part")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the launcher and its local cluster
        proc.wait(timeout=30)
    done = len(list(parts.glob("part-*.ptpart")))
    assert 1 <= done < 4 and not out.exists()
    before = starts(marks)
    resumed = ok(farm(scene, "-f", out, "--parts", 4, "--workers", 1, "--binary", wrapper, *FLAGS))
    assert starts(marks) - before == 4 - done
    assert f"{done} of 4 parts already done" in resumed.stderr
    assert out.read_bytes() == want
    # A damaged part is rendered again; a finished job renders nothing.
    damaged = parts / "part-0-of-4.ptpart"
    damaged.write_bytes(damaged.read_bytes()[:-3])
    before = starts(marks)
    again = ok(farm(scene, "-f", out, "--parts", 4, "--workers", 1, "--binary", wrapper, *FLAGS))
    assert starts(marks) - before == 1 and "re-rendering part 0/4" in again.stderr
    assert out.read_bytes() == want
    before = starts(marks)
    ok(farm(scene, "-f", out, "--parts", 4, "--binary", wrapper, *FLAGS))
    assert starts(marks) == before


def test_a_joined_cluster_renders_the_same_bytes(binary, scene, tmp_path):
    """dask scheduler + dask worker processes, joined with --scheduler (as on many machines)."""
    bindir = Path(sys.executable).parent
    dask_cli = bindir / "dask"
    if not dask_cli.exists():
        pytest.fail(f"{dask_cli} missing: install distributed in this environment")
    file = tmp_path / "scheduler.json"
    env = dict(os.environ, DASK_LOGGING__DISTRIBUTED="critical")
    procs = [subprocess.Popen([str(dask_cli), "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(file)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)]
    try:
        address = wait_for(lambda: file.exists() and json.loads(file.read_text() or "{}").get("address"),
                           "the scheduler")
        procs.append(subprocess.Popen([str(dask_cli), "worker", address, "--nthreads", "1", "--no-dashboard",
                                       "--host", "127.0.0.1"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, start_new_session=True))
        proc = ok(farm(scene, "-f", tmp_path / "farm.png", "--parts", 3, "--scheduler", address,
                       "--binary", binary, *FLAGS))
        assert (tmp_path / "farm.png").read_bytes() == whole(binary, scene, tmp_path / "whole.png")
        assert "Merged 3 parts" in proc.stdout
    finally:
        for p in procs:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait(timeout=30)


def test_bad_inputs_are_one_line_errors(binary, scene, tmp_path):
    out = tmp_path / "x.png"
    one_line_error(farm(scene, "-f", out, "--parts", 2, "--binary", tmp_path / "nope"), "no such executable")
    one_line_error(farm(scene, "-f", out, "--parts", 2, "--binary", binary, "--scheduler", "tcp://127.0.0.1:9",
                        "--connect-timeout", 2), "cannot reach the scheduler tcp://127.0.0.1:9")
    one_line_error(farm(tmp_path / "missing.dae", "-f", out, "--parts", 2, "--binary", binary), "missing.dae")
    one_line_error(farm(scene, "-f", out, "--parts", 2, "--binary", binary, "-s", "0"), "-s")
    one_line_error(farm(scene, "-f", out, "--parts", 99, "--binary", binary, *FLAGS), "cannot be cut into 99 parts")
    one_line_error(farm(scene, "-f", out, "--parts", 4, "--binary", binary, *FLAGS, "-a", "4", "0.1"), "adaptive")
    one_line_error(farm(scene, "-f", tmp_path / "x.jpg", "--parts", 2, "--binary", binary), ".png or .exr")
    one_line_error(farm(scene, "-f", out, "--binary", binary), "--parts")
    assert not out.exists()
    # A parts directory of another job, and a foreign part inside this job's directory.
    ok(farm(scene, "-f", out, "--parts", 2, "--workers", 1, "--binary", binary, *FLAGS))
    one_line_error(farm(scene, "-f", out, "--parts", 2, "--binary", binary, *FLAGS, "--seed", "9"),
                   "holds the parts of another job (its flags differ)")
    foreign = tmp_path / "foreign.ptpart"
    subprocess.run([binary, *FLAGS, "--seed", "9", "--part", "1/2", "-f", foreign, scene], check=True,
                   capture_output=True, timeout=TIMEOUT)
    shutil.copy(foreign, tmp_path / "x.png.parts" / "part-1-of-2.ptpart")
    out.unlink()
    one_line_error(farm(scene, "-f", out, "--parts", 2, "--binary", binary, *FLAGS), "other flags")
    assert not out.exists()
