"""What the benchmark scripts share: the machine they ran on, and one `rvegen` command timed as a
user feels it (wall time and peak memory of the whole process, by GNU time)."""
import json
import os
import platform
import subprocess
import sys


def machine():
    """'<CPU model>, <n> cores, <OS>': the line every table states."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return "%s, %d cores, %s" % (model, os.cpu_count(), platform.platform(terse=True))


def timed(cmd):
    """Runs cmd under /usr/bin/time; returns (exit code, wall seconds, peak MiB, stderr)."""
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M"] + list(cmd), capture_output=True,
                       text=True)
    lines = p.stderr.strip().splitlines()
    last = [ln for ln in lines if ln.startswith("TIME ")][-1].split()
    rest = "\n".join(ln for ln in lines if not ln.startswith("TIME "))
    return p.returncode, float(last[1]), int(last[2]) / 1024.0, rest


def generate(exe, scene, work, name, extra=()):
    """Writes `scene` to WORK/NAME.json, runs `rvegen generate -q` on it into WORK/NAME under
    GNU time; returns (exit code, wall seconds, peak MiB, report.json as a dict)."""
    path = os.path.join(work, name + ".json")
    out = os.path.join(work, name)
    with open(path, "w") as f:
        json.dump(scene, f)
    rc, wall, peak, err = timed([exe, "generate", "-q", path, "-o", out] + list(extra))
    try:
        with open(os.path.join(out, "report.json")) as f:
            report = json.load(f)
    except OSError:
        raise SystemExit("rvegen generate wrote no report for %s (exit %d): %s"
                         % (name, rc, err[-500:]))
    return rc, wall, peak, report


def option(name, default, kind=float):
    """The comma-separated values of `--name VALUES` in sys.argv, converted by kind (and removed
    from sys.argv), or default when it is not given."""
    if name in sys.argv:
        k = sys.argv.index(name)
        value = sys.argv[k + 1]
        del sys.argv[k:k + 2]
        return [kind(v) for v in value.split(",")]
    return default
