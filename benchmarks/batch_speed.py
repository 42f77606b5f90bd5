"""`densepeds batch` on Ray against `densepeds run` on the same clips one after another.

    python benchmarks/batch_speed.py [--frames 40] [--rounds 1] [--out benchmarks/results/batch.md]

Clips: two parts of each real video (PETS09-S2L1 ``vtest.avi`` and ``MOT20-01-raw.mp4`` from
../shared), written as short .mp4 files; full method (YOLOv8-seg detector, OSNet segmented-box
re-ID, FRVO). Per round, interleaved: the sequential ``densepeds run`` processes, then
``densepeds batch`` with 1 and with 2 workers (a local Ray each); the machine's load average is
printed beside every figure. Then a two-node Ray cluster simulated on this machine (``ray start
--head`` and a second ``ray start --address``, one CPU and a resource of its own each, on
127.0.0.1): where the jobs ran, where the models were copied, and a worker killed in the middle of
a batch (the batch goes on; the rerun redoes only that input). Every batch's tracks are compared
with the sequential runs' (they must be identical).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("DENSEPEDS_SHARED", REPO.parent / "shared"))
VIDEOS = {
    "pets": SHARED / "data" / "PETS09-S2L1-dev" / "vtest.avi",
    "mot20": SHARED / "data" / "MOT20-01-dev" / "MOT20-01-raw.mp4",
}
RUN_OPTIONS = ["--detector", "yoloseg"]
# `densepeds run`, printing the process's peak resident memory at the end.
RUN_WITH_RSS = (
    "import resource, sys\n"
    "from densepeds.cli import main\n"
    "rc = main(sys.argv[1:])\n"
    "print('max_rss_mb', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)\n"
    "sys.exit(rc)\n"
)


def load() -> str:
    return "load {:.1f}/{:.1f}/{:.1f}".format(*os.getloadavg())


def write_clips(folder: Path, frames: int) -> list[Path]:
    """Frames 1..F and F+1..2F of each video, as .mp4 files."""
    folder.mkdir(parents=True, exist_ok=True)
    clips = []
    for name, video in VIDEOS.items():
        cap = cv2.VideoCapture(str(video))
        fps = cap.get(cv2.CAP_PROP_FPS) or 25.0
        for part in range(2):
            path = folder / f"{name}-{part + 1}.mp4"
            writer = None
            for _ in range(frames):
                ok, image = cap.read()
                if not ok:
                    raise SystemExit(f"{video}: fewer than {2 * frames} frames")
                if writer is None:
                    h, w = image.shape[:2]
                    writer = cv2.VideoWriter(
                        str(path), cv2.VideoWriter.fourcc(*"mp4v"), fps, (w, h)
                    )
                writer.write(image)
            assert writer is not None
            writer.release()
            clips.append(path)
        cap.release()
    return clips


def env(cluster: bool = False) -> dict[str, str]:
    e = dict(os.environ)
    e.setdefault("DENSEPEDS_MODEL_DIR", str(SHARED / "models"))
    if cluster:
        # `ray start` turns Ray's token authentication on; its clients must use it too.
        e["RAY_AUTH_MODE"] = "token"
    return e


def sequential(clips: list[Path], out: Path) -> dict[str, Any]:
    """`densepeds run` per clip, one process after another."""
    out.mkdir(parents=True, exist_ok=True)
    per_clip = []
    before = load()
    cpu_start = children_cpu()
    start = time.perf_counter()
    for clip in clips:
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-c", RUN_WITH_RSS, "run", str(clip), *RUN_OPTIONS, "-q"]
            + ["--out", str(out / f"{clip.stem}.txt")],
            env=env(),
            capture_output=True,
            text=True,
            check=True,
        )
        wall = time.perf_counter() - t0
        m = re.search(r": (\d+) frames, (\d+) tracks .*; ([\d.]+) frames/s", proc.stdout)
        assert m, proc.stdout
        frames, fps = int(m.group(1)), float(m.group(3))
        rss = float(proc.stdout.rsplit("max_rss_mb", 1)[1])
        per_clip.append(
            {
                "clip": clip.stem,
                "frames": frames,
                "wall": wall,
                "fps": fps,
                "overhead": wall - frames / fps,
                "rss": rss,
            }
        )
    wall = time.perf_counter() - start
    cpu = children_cpu() - cpu_start
    frames = sum(c["frames"] for c in per_clip)
    return {
        "wall": wall,
        "frames": frames,
        "rate": frames / wall,
        "cpu": cpu,
        "busy": wall,
        "clips": per_clip,
        "load": f"{before} -> {load()}",
    }


def batch(
    clips_dir: Path, out: Path, workers: int | None, address: str | None = None
) -> dict[str, Any]:
    """`densepeds batch` over the clips folder in a fresh output folder."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "densepeds", "batch", str(clips_dir), "--out", str(out)]
    cmd += RUN_OPTIONS + ["-q"]
    if workers is not None:
        cmd += ["--workers", str(workers)]
    if address is not None:
        cmd += ["--address", address]
    before = load()
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env(address is not None), capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(f"batch failed ({proc.returncode}): {proc.stdout}\n{proc.stderr}")
    summary = json.loads((out / "batch.json").read_text())
    frames = sum(r["frames"] for r in summary["inputs"])
    busy = summary["seconds"] - summary["start_seconds"]
    return {
        "wall": wall,
        "frames": frames,
        "rate": frames / wall,
        "cpu": sum(r["cpu_seconds"] for r in summary["inputs"]),
        "busy": busy,
        "rate_started": frames / busy,
        "start": summary["start_seconds"],
        "summary": summary,
        "load": f"{before} -> {load()}",
    }


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def same_tracks(a: Path, b: Path, names: list[str]) -> bool:
    return all((a / f"{n}.txt").read_bytes() == (b / f"{n}.txt").read_bytes() for n in names)


# --- a two-node cluster on this machine ---------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Cluster:
    """Two Ray nodes on 127.0.0.1, each from a `ray start --block` process started here (so
    that stopping them stops exactly these nodes)."""

    def __init__(self) -> None:
        self.port = free_port()
        self.address = f"127.0.0.1:{self.port}"
        self.procs: list[subprocess.Popen[bytes]] = []
        self.logs = tempfile.mkdtemp(prefix="densepeds-cluster-")
        self.node_addresses = ""

    def _start(self, args: list[str], log: str) -> None:
        with open(Path(self.logs) / log, "wb") as fh:
            self.procs.append(
                subprocess.Popen(
                    ["ray", "start", "--block", "--node-ip-address", "127.0.0.1"]
                    + ["--disable-usage-stats", *args],
                    env=env(cluster=True),
                    stdout=fh,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            )

    def start(self) -> float:
        t0 = time.perf_counter()
        self._start(
            ["--head", "--port", str(self.port), "--num-cpus", "1", "--include-dashboard", "false"]
            + ["--resources", '{"node_a": 1}'],
            "head.log",
        )
        self.wait(1)
        self._start(
            ["--address", self.address, "--num-cpus", "1", "--resources", '{"node_b": 1}'],
            "second.log",
        )
        self.wait(2)
        return time.perf_counter() - t0

    def wait(self, nodes: int, timeout: float = 180.0) -> None:
        probe = (
            "import ray,sys,logging;ray.init(address=sys.argv[1],logging_level=logging.ERROR);"
            "alive=[n['NodeManagerAddress'] for n in ray.nodes() if n['Alive']];"
            "print(','.join(sorted(set(alive))), len(alive))"
        )
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            proc = subprocess.run(
                [sys.executable, "-c", probe, self.address],
                env=env(cluster=True),
                capture_output=True,
                text=True,
            )
            if proc.returncode == 0 and proc.stdout.strip().endswith(f" {nodes}"):
                self.node_addresses = proc.stdout.split()[-2]
                return
            time.sleep(2)
        raise SystemExit(f"the cluster did not reach {nodes} nodes (logs in {self.logs})")

    def stop(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in reversed(self.procs):
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def remove_model_copies(cluster: dict[str, Any]) -> None:
    """Delete the models the cluster's nodes copied (one folder per node id)."""
    from densepeds.batch.worker import node_cache_dir

    nodes = {
        rec["node"]
        for part in (cluster.get("batch"), cluster.get("killed", {}).get("first"))
        if part
        for rec in (part["summary"]["inputs"] if "summary" in part else part["inputs"])
        if rec.get("node")
    }
    for node in nodes:
        for folder in node_cache_dir().parent.glob(f"{node}*"):
            shutil.rmtree(folder, ignore_errors=True)


def killed_worker(clips_dir: Path, out: Path, victim: str, address: str) -> dict[str, Any]:
    """A batch whose worker on ``victim`` is killed once it is running; then the rerun."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "densepeds", "batch", str(clips_dir), "--out", str(out)]
    cmd += [*RUN_OPTIONS, "-q", "--address", address]
    proc = subprocess.Popen(
        cmd, env=env(cluster=True), stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    record = out / f"{victim}.json"
    pid = None
    end = time.monotonic() + 300
    while pid is None and time.monotonic() < end and proc.poll() is None:
        try:
            data = json.loads(record.read_text())
            if data["status"] == "running":
                pid = int(data["pid"])
        except (OSError, ValueError):
            time.sleep(0.1)
    if pid is None:
        proc.kill()
        raise SystemExit(f"{victim} never ran")
    time.sleep(2.0)  # well inside its tracking
    os.kill(pid, signal.SIGKILL)
    first_out, _ = proc.communicate(timeout=600)
    first = json.loads((out / "batch.json").read_text())
    t0 = time.perf_counter()
    rerun = subprocess.run(cmd, env=env(cluster=True), capture_output=True, text=True)
    second = json.loads((out / "batch.json").read_text())
    return {
        "first_rc": proc.returncode,
        "first": first,
        "first_table": first_out.decode(),
        "rerun_rc": rerun.returncode,
        "rerun": second,
        "rerun_wall": time.perf_counter() - t0,
    }


# --- report ---------------------------------------------------------------------------------


def report(args: argparse.Namespace, rounds: list[dict[str, Any]], cluster: dict[str, Any]) -> str:
    import densepeds

    lines = [
        "# `densepeds batch`: throughput, overhead, a simulated cluster",
        "",
        f"`python benchmarks/batch_speed.py --frames {args.frames} --rounds {args.rounds}` "
        f"(densepeds {densepeds.__version__}, ray {_ray_version()}, Python "
        f"{sys.version.split()[0]}), {os.cpu_count()} cores shared with other jobs: the load "
        "average (1/5/15 min) before and after each measurement is printed beside it.",
        "",
        f"Clips: frames 1-{args.frames} and {args.frames + 1}-{2 * args.frames} of PETS09-S2L1 "
        "`vtest.avi` (768x576) and of `MOT20-01-raw.mp4` (960x540), 4 clips, "
        f"{4 * args.frames} frames; options `{' '.join(RUN_OPTIONS)}` (YOLOv8-seg, OSNet "
        "segmented boxes, FRVO). *sequential*: `densepeds run` on each clip, one process after "
        "another; *batch N*: `densepeds batch CLIPS --workers N` with a local Ray (whole command, "
        "Ray's start included, and after Ray's start).",
        "",
        "## Throughput",
        "",
        "| round | mode | wall s | frames/s | x sequential | frames/s after Ray start | "
        "x sequential | CPU s per frame | cores busy | tracks = sequential | load |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|",
    ]
    for i, r in enumerate(rounds, 1):
        seq = r["sequential"]
        lines.append(
            f"| {i} | sequential | {seq['wall']:.1f} | {seq['rate']:.2f} | 1.00 | | | "
            f"{seq['cpu'] / seq['frames']:.2f} | {seq['cpu'] / seq['busy']:.2f} | | "
            f"{seq['load']} |"
        )
        for key in ("batch1", "batch2"):
            b = r[key]
            lines.append(
                f"| {i} | batch {key[-1]} | {b['wall']:.1f} | {b['rate']:.2f} | "
                f"{b['rate'] / seq['rate']:.2f} | {b['rate_started']:.2f} | "
                f"{b['rate_started'] / seq['rate']:.2f} | {b['cpu'] / b['frames']:.2f} | "
                f"{b['cpu'] / b['busy']:.2f} | {b['same']} | {b['load']} |"
            )
    lines += ["", *verdict(rounds)]
    last = rounds[-1]
    lines += [
        "",
        "*CPU s per frame*: CPU time (all threads) of the `run` processes, or of the batch "
        "workers' jobs, per frame; *cores busy*: that CPU time over the wall time (after Ray's "
        "start for a batch): the cores the mode kept busy on a machine it shared.",
        "",
        "## Overhead per input and memory",
        "",
        "*sequential*: a `densepeds run` process's wall time less its tracking time (Python "
        "start, imports, opening the clip, loading both models). *batch*: a job's wall time less "
        "its tracking time, and the part spent loading models (only the first job of a worker "
        "loads them). Memory: peak resident size of a `run` process and of each batch worker.",
        "",
        "| mode | clip | overhead s | model load s | peak RSS MB |",
        "|---|---|---:|---:|---:|",
    ]
    for c in last["sequential"]["clips"]:
        lines.append(f"| sequential | {c['clip']} | {c['overhead']:.2f} | | {c['rss']:.0f} |")
    for key in ("batch1", "batch2"):
        for rec in last[key]["summary"]["inputs"]:
            overhead = rec["seconds"] - rec["frames"] / rec["fps"] if rec["fps"] else 0.0
            lines.append(
                f"| batch {key[-1]} | {rec['name']} | {overhead:.2f} | {rec['load_seconds']:.2f} "
                f"| {rec['max_rss_mb']:.0f} |"
            )
        lines.append(f"| batch {key[-1]} | Ray start | {last[key]['start']:.1f} | | |")
    if cluster:
        lines += ["", "## Two nodes on one machine", ""]
        lines += cluster_lines(cluster)
    return "\n".join(lines) + "\n"


def verdict(rounds: list[dict[str, Any]]) -> list[str]:
    """The issue's goals against these figures (median over rounds, after Ray's start)."""

    def median(values: list[float]) -> float:
        values = sorted(values)
        mid = len(values) // 2
        return values[mid] if len(values) % 2 else (values[mid - 1] + values[mid]) / 2

    ratio = {
        n: median([r[f"batch{n}"]["rate_started"] / r["sequential"]["rate"] for r in rounds])
        for n in (1, 2)
    }
    whole = median([r["batch2"]["rate"] / r["sequential"]["rate"] for r in rounds])
    busy = [r[k]["cpu"] / r[k]["busy"] for r in rounds for k in ("sequential", "batch1", "batch2")]
    return [
        f"Goals (median of {len(rounds)} round(s), after Ray's start): 2 workers >= 1.8x the "
        f"sequential runs: {ratio[2]:.2f}x, {'met' if ratio[2] >= 1.8 else 'not met'} "
        f"({whole:.2f}x with Ray's start); 1 worker no slower: {ratio[1]:.2f}x, "
        f"{'met' if ratio[1] >= 1.0 else 'not met'}. Every mode kept {min(busy):.2f}-"
        f"{max(busy):.2f} of the 2 cores busy on average: the machine was shared, so these "
        "ratios measure the share of the cores each mode got as much as its parallelism.",
    ]


def cluster_lines(c: dict[str, Any]) -> list[str]:
    b = c["batch"]
    nodes = sorted({r["node"] for r in b["summary"]["inputs"]})
    rows = [
        f"`ray start --head --num-cpus 1 --resources '{{\"node_a\": 1}}'` and `ray start "
        f"--address ... --num-cpus 1 --resources '{{\"node_b\": 1}}'`, both given "
        f"`--node-ip-address 127.0.0.1` (Ray registers a loopback address as the machine's own, "
        f"here {c['node_addresses']}; its token authentication is on), started in "
        f"{c['start_seconds']:.0f} s; `densepeds batch CLIPS --address "
        f"127.0.0.1:PORT`: {b['wall']:.1f} s, {b['rate']:.2f} frames/s, tracks = sequential: "
        f"{b['same']} ({b['load']}).",
        "",
        "| clip | node | models copied to the node by this job | seconds |",
        "|---|---|---|---:|",
    ]
    for rec in b["summary"]["inputs"]:
        fetched = ", ".join(rec["fetched_models"]) or "-"
        rows.append(f"| {rec['name']} | {rec['node']} | {fetched} | {rec['seconds']:.1f} |")
    rows += ["", f"Jobs ran on {len(nodes)} node(s).", ""]
    k = c["killed"]
    rows += [
        f"Worker killed in the middle of a batch (SIGKILL to the process tracking "
        f"`{c['victim']}`, 2 s into its job): the batch finished with exit status "
        f"{k['first_rc']}:",
        "",
        "| clip | status | note |",
        "|---|---|---|",
    ]
    for rec in k["first"]["inputs"]:
        rows.append(f"| {rec['name']} | {rec['status']} | {rec['error'] or ''} |")
    ran = [r["name"] for r in k["rerun"]["inputs"] if not r["skipped"]]
    rows += [
        "",
        f"The rerun (exit status {k['rerun_rc']}, {k['rerun_wall']:.1f} s) ran only {ran}; all "
        f"done: {all(r['status'] == 'done' for r in k['rerun']['inputs'])}; its tracks = "
        f"sequential: {c['killed_same']}.",
    ]
    return rows


def _ray_version() -> str:
    import ray

    return str(ray.__version__)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=40, help="frames per clip")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--out", type=Path, help="write the markdown report here")
    parser.add_argument("--no-cluster", action="store_true")
    args = parser.parse_args()
    for video in VIDEOS.values():
        if not video.is_file():
            raise SystemExit(f"needs {video} (../shared)")
    work = Path(tempfile.mkdtemp(prefix="densepeds-batch-bench-"))
    try:
        clips = write_clips(work / "clips", args.frames)
        names = [c.stem for c in clips]
        rounds = []
        for r in range(args.rounds):
            result: dict[str, Any] = {"sequential": sequential(clips, work / "seq")}
            print(f"round {r + 1} sequential: {result['sequential']}", flush=True)
            for workers in (1, 2):
                b = batch(work / "clips", work / f"batch{workers}", workers)
                b["same"] = same_tracks(work / "seq", work / f"batch{workers}", names)
                result[f"batch{workers}"] = b
                print(
                    f"round {r + 1} batch {workers}: {b['wall']:.1f} s, {b['rate']:.2f} f/s, "
                    f"same {b['same']}, {b['load']}",
                    flush=True,
                )
            rounds.append(result)
        cluster: dict[str, Any] = {}
        if not args.no_cluster:
            c = Cluster()
            try:
                cluster["start_seconds"] = c.start()
                cluster["node_addresses"] = c.node_addresses
                b = batch(work / "clips", work / "cluster", None, c.address)
                b["same"] = same_tracks(work / "seq", work / "cluster", names)
                cluster["batch"] = b
                print(f"cluster batch: {b['wall']:.1f} s, same {b['same']}", flush=True)
                victim = names[-1]
                cluster["victim"] = victim
                cluster["killed"] = killed_worker(
                    work / "clips", work / "killed", victim, c.address
                )
                cluster["killed_same"] = same_tracks(work / "seq", work / "killed", names)
            finally:
                c.stop()
                remove_model_copies(cluster)
        text = report(args, rounds, cluster)
        print(text)
        if args.out:
            args.out.write_text(text)
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
