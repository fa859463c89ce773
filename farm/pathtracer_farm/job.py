"""A farm job: plan, check, submit the missing parts to Dask, keep them on disk, merge.

One frame (scene) is ``N`` parts, ``pathtracer --part K/N``; part K is kept as
``PARTS_DIR/part-K-of-N.ptpart`` (written to a temporary name and renamed), beside a
``job.json`` naming the scene's SHA-256, the flags, N and the renderer version. A rerun of the
same command finds the valid parts there and renders only the others; a parts directory of
another job is refused.
"""

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import uuid

# Quiet Dask's logs (in this process and in the worker processes it starts): worker deaths
# and retries are reported by this launcher, one line each.
os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")

from . import worker as farm_worker  # noqa: E402


class JobError(Exception):
    """A one-line error that ends the job."""


class Frame:
    """One scene of the job and where its parts and image go."""

    def __init__(self, scene, output, parts_dir, n):
        self.scene, self.output, self.parts_dir, self.n = scene, output, parts_dir, n
        try:
            with open(scene, "rb") as f:
                self.data = f.read()
        except OSError as e:
            raise JobError(f"{scene}: cannot read: {e.strerror}") from None
        self.name = os.path.basename(scene)
        self.sha256 = hashlib.sha256(self.data).hexdigest()
        self.done = set()

    def part_path(self, k):
        return os.path.join(self.parts_dir, f"part-{k}-of-{self.n}.ptpart")

    def missing(self):
        return [k for k in range(self.n) if k not in self.done]


def run(args, flags):
    """The whole job; returns the exit code."""
    if args.parts < 1:
        raise JobError(f"--parts {args.parts}: expected at least 1")
    if args.retries < 0:
        raise JobError(f"--retries {args.retries}: expected at least 0")
    if args.workers is not None and args.workers < 1:
        raise JobError(f"--workers {args.workers}: expected at least 1")
    binary = find_binary(args.binary)
    version = local_version(binary)
    frames = plan_frames(args)
    for frame in frames:
        preflight(binary, flags, frame)
        open_parts_dir(frame, flags, version)
        find_done_parts(binary, frame)
    todo = sum(len(f.missing()) for f in frames)
    total = sum(f.n for f in frames)
    if todo < total:
        say(f"{total - todo} of {total} parts already done (resuming)")
    if todo:
        threads = args.t
        with cluster(args) as client:
            check_workers(client, binary, version)
            if threads is None and args.workers:
                threads = str(max(1, (os.cpu_count() or 1) // args.workers))
            part_flags = flags + (["-t", threads] if threads else [])
            render_parts(client, binary, part_flags, frames, args.retries, total)
    for frame in frames:
        merge(binary, frame)
    return 0


def say(text):
    print(f"[pathtracer-farm] {text}", file=sys.stderr, flush=True)


def find_binary(binary):
    if binary is None:
        found = shutil.which("pathtracer")
        if found is None:
            raise JobError("no pathtracer binary on PATH (give --binary PATH)")
        return os.path.abspath(found)
    if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
        raise JobError(f"--binary {binary}: no such executable file")
    return os.path.abspath(binary)


def local_version(binary):
    line = farm_worker.check_binary(binary)
    if line.startswith("error:"):
        raise JobError(line[len("error: "):])
    return line


def plan_frames(args):
    out = args.output
    if len(args.scenes) > 1 and "{name}" not in out:
        raise JobError(f"-f {out}: with several scenes the output must hold {{name}} (e.g. frames/{{name}}.png)")
    frames = []
    for scene in args.scenes:
        stem = os.path.splitext(os.path.basename(scene))[0]
        output = out.replace("{name}", stem)
        if not output.lower().endswith((".png", ".exr")):
            raise JobError(f"-f {output}: output must end in .png or .exr")
        parts_dir = (args.parts_dir.replace("{name}", stem) if args.parts_dir else output + ".parts")
        if args.parts_dir and len(args.scenes) > 1 and "{name}" not in args.parts_dir:
            parts_dir = os.path.join(args.parts_dir, stem)
        frames.append(Frame(scene, output, parts_dir, args.parts))
    outputs = [f.output for f in frames]
    if len(set(outputs)) != len(outputs):
        raise JobError(f"-f {out}: two scenes would write the same output")
    return frames


def preflight(binary, flags, frame):
    """The renderer checks the flags, the plan and the scene without rendering (--info)."""
    with tempfile.TemporaryDirectory(prefix="pathtracer-farm-check-") as tmp:
        cmd = [binary, *flags, "--part", f"0/{frame.n}", "-f", os.path.join(tmp, "x.ptpart"),
               "--info", frame.scene]
        proc = subprocess.run(cmd, capture_output=True, check=False)
    if proc.returncode != 0:
        lines = proc.stderr.decode(errors="replace").strip().splitlines()
        raise JobError(lines[-1].removeprefix("error: ") if lines else f"{binary} failed")


def open_parts_dir(frame, flags, version):
    """Creates the parts directory with its job.json, or checks that it is this job's."""
    want = {"scene": frame.name, "scene_sha256": frame.sha256, "flags": flags,
            "parts": frame.n, "renderer": version}
    path = os.path.join(frame.parts_dir, "job.json")
    try:
        os.makedirs(frame.parts_dir, exist_ok=True)
    except OSError as e:
        raise JobError(f"{frame.parts_dir}: cannot create: {e.strerror}") from None
    has_parts = any(n.endswith(".ptpart") for n in os.listdir(frame.parts_dir))
    if os.path.exists(path) and has_parts:  # without parts, nothing is lost by starting again
        try:
            with open(path) as f:
                have = json.load(f)
        except (OSError, ValueError) as e:
            raise JobError(f"{path}: unreadable job file ({e}); remove it to start again") from None
        if have != want:
            diff = ", ".join(k for k in want if have.get(k) != want[k])
            raise JobError(f"{frame.parts_dir} holds the parts of another job (its {diff} differ); "
                           f"remove it or give another --parts-dir")
        return
    write_atomically(path, json.dumps(want, indent=1).encode())


def find_done_parts(binary, frame):
    """Parts on disk that the renderer reads as whole (checksum) count as done."""
    for k in range(frame.n):
        path = frame.part_path(k)
        if not os.path.exists(path):
            continue
        proc = subprocess.run([binary, "part-info", path], capture_output=True, check=False)
        if proc.returncode == 0:
            frame.done.add(k)
        else:
            why = proc.stderr.decode(errors="replace").strip()
            say(f"re-rendering part {k}/{frame.n} of {frame.name}: {why}")


def write_atomically(path, data):
    folder, name = os.path.split(path)
    tmp = os.path.join(folder, f".{name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise JobError(f"{path}: cannot write: {e.strerror}") from None


class cluster:
    """A Dask client: a LocalCluster of --workers processes on 127.0.0.1, or --scheduler."""

    def __init__(self, args):
        self.args, self.cluster, self.client = args, None, None

    def __enter__(self):
        from distributed import Client, LocalCluster

        a = self.args
        if a.scheduler:
            try:
                self.client = Client(a.scheduler, timeout=f"{a.connect_timeout}s")
            except (OSError, TimeoutError, ValueError) as e:
                raise JobError(f"cannot reach the scheduler {a.scheduler}: {one_line(e)}") from None
        else:
            self.cluster = LocalCluster(n_workers=a.workers or 1, threads_per_worker=1,
                                        processes=True, host="127.0.0.1", dashboard_address=None)
            self.client = Client(self.cluster)
        return self.client

    def __exit__(self, *exc):
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        return False


def one_line(e):
    text = " ".join(str(e).split()) or type(e).__name__
    return text


def check_workers(client, binary, version):
    """Every worker must run the same renderer version as the merge here."""
    try:
        client.wait_for_workers(1, timeout=60)
    except TimeoutError:
        raise JobError("no Dask worker joined the scheduler within 60 s") from None
    for address, line in sorted(client.run(farm_worker.check_binary, binary).items()):
        if line.startswith("error:"):
            raise JobError(f"worker {address}: {line[len('error: '):]}")
        if line != version:
            raise JobError(f"worker {address} runs '{line}', this machine '{version}': install one version")


def render_parts(client, binary, flags, frames, retries, total):
    """Submits the missing parts, keeps each as it arrives, reports progress and retries."""
    from distributed import as_completed

    job = uuid.uuid4().hex
    futures = {}
    for frame in frames:
        if not frame.missing():
            continue
        # A task that returns the scene, not `scatter`: the scheduler keeps the bytes in the
        # task and computes the result again if the worker holding it dies.
        data = client.submit(farm_worker.scene_bytes, frame.data, pure=False,
                             key=f"pathtracer-scene-{job[:8]}-{id(frame)}")
        for k in frame.missing():
            fut = client.submit(farm_worker.render_part, job, binary, frame.name, data, flags, k, frame.n,
                                pure=False, retries=retries, key=f"pathtracer-part-{k}-of-{frame.n}-{job[:8]}-{id(frame)}")
            futures[fut] = (frame, k)
    start = time.monotonic()
    progress = Progress(total, total - len(futures))
    for fut in as_completed(list(futures)):
        frame, k = futures[fut]
        try:
            data = fut.result()
        except Exception as e:  # the part's last attempt failed, or its worker kept dying
            for other in futures:
                other.cancel()
            raise JobError(f"part {k}/{frame.n} of {frame.name} failed after {retries} retries: {one_line(e)}") from None
        write_atomically(frame.part_path(k), data)
        frame.done.add(k)
        progress.step()
    progress.finish()
    report_retries(client, job, frames)
    elapsed = time.monotonic() - start
    say(f"{len(futures)} parts rendered in {elapsed:.2f} s")


def report_retries(client, job, frames):
    """Parts started more than once: a worker died or the renderer failed, and Dask retried."""
    starts = {}
    try:
        events = client.get_events("pathtracer-farm")
    except Exception:  # an old scheduler without events: no report
        return
    for _, msg in events:
        if isinstance(msg, dict) and msg.get("job") == job:
            starts.setdefault((msg["scene"], msg["part"]), []).append(msg["worker"])
    n = frames[0].n
    for (scene, k), workers in sorted(starts.items()):
        if len(workers) > 1:
            say(f"part {k}/{n} of {scene} retried: started {len(workers)} times (on {', '.join(workers)})")


class Progress:
    """A bar of parts done on stderr: redrawn in place on a terminal, a line per part otherwise."""

    def __init__(self, total, done):
        self.total, self.done = total, done
        self.tty = sys.stderr.isatty()
        self.draw()

    def draw(self):
        width = 30
        filled = width * self.done // max(self.total, 1)
        bar = f"[pathtracer-farm] parts [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total}"
        print(("\r" + bar) if self.tty else bar, end="" if self.tty else "\n", file=sys.stderr, flush=True)

    def step(self):
        self.done += 1
        self.draw()

    def finish(self):
        if self.tty:
            print(file=sys.stderr, flush=True)


def merge(binary, frame):
    """``pathtracer merge``: its statistics (summed over the parts) go to stdout."""
    parts = [frame.part_path(k) for k in range(frame.n)]
    proc = subprocess.run([binary, "merge", *parts, "-f", frame.output], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, check=False)
    sys.stdout.write(proc.stdout.decode(errors="replace"))
    sys.stdout.flush()
    if proc.returncode != 0:
        lines = proc.stderr.decode(errors="replace").strip().splitlines()
        raise JobError(lines[-1].removeprefix("error: ") if lines else "merge failed")
