"""What runs on a Dask worker: one part of a render, by the pathtracer binary.

The scene travels with the task (as bytes), so workers need no shared filesystem; each worker
process keeps the scene file in its own temporary directory. The part file comes back to the
client as bytes.
"""

import hashlib
import os
import subprocess
import tempfile

_SCENES = {}  # sha256 -> path of the scene file on this worker


class PartFailed(RuntimeError):
    """The renderer failed (non-zero exit, killed): Dask retries the task."""


def _scene_file(name, data):
    digest = hashlib.sha256(data).hexdigest()
    path = _SCENES.get(digest)
    if path is None or not os.path.exists(path):
        folder = tempfile.mkdtemp(prefix="pathtracer-farm-scene-")
        path = os.path.join(folder, os.path.basename(name))
        with open(path, "wb") as f:
            f.write(data)
        _SCENES[digest] = path
    return path


def scene_bytes(data):
    """The scene file's bytes, as a task result that parts depend on."""
    return data


def _log_start(job, scene, k):
    """Tells the client a part started (it counts starts to report retries)."""
    try:
        from distributed import get_worker

        worker = get_worker()
        worker.log_event("pathtracer-farm", {"job": job, "scene": scene, "part": k, "worker": worker.address})
    except (ImportError, ValueError):
        pass  # not inside a Dask worker (tests call this directly)


def render_part(job, binary, scene_name, scene_data, flags, k, n):
    """Renders part ``k`` of ``n``; returns (part file bytes, seconds the renderer ran)."""
    _log_start(job, scene_name, k)
    scene = _scene_file(scene_name, scene_data)
    with tempfile.TemporaryDirectory(prefix="pathtracer-farm-part-") as tmp:
        out = os.path.join(tmp, "part.ptpart")
        cmd = [binary, *flags, "--quiet", "--part", f"{k}/{n}", "-f", out, scene]
        try:
            proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False)
        except OSError as e:
            raise PartFailed(f"cannot run {binary}: {e.strerror or e}") from None
        if proc.returncode != 0:
            lines = proc.stderr.decode(errors="replace").strip().splitlines()
            why = lines[-1] if lines else f"killed by signal {-proc.returncode}" if proc.returncode < 0 else ""
            raise PartFailed(f"part {k}/{n}: {os.path.basename(binary)} exited with {proc.returncode}: {why}")
        with open(out, "rb") as f:
            return f.read()


def check_binary(binary):
    """On a worker: the renderer's version line, or an error message starting 'error:'."""
    try:
        proc = subprocess.run([binary, "--version"], capture_output=True, check=False, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"error: cannot run {binary}: {getattr(e, 'strerror', None) or e}"
    if proc.returncode != 0:
        return f"error: {binary} --version exited with {proc.returncode}"
    return proc.stdout.decode(errors="replace").strip()
