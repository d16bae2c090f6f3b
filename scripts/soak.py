#!/usr/bin/env python3
"""make soak: a long run of good and hostile clients against one mts-server.

Good clients (mts-stress, applying and not, both forms, partial stops; and
mts-client --resume, whose final checksum must equal an unbroken run's) run
in rounds beside hostile ones (idle, trickling a HELLO, sending garbage,
resetting mid-stream) against `mts-server --workers 2`. Every 5 s the
server's resident memory and open descriptors are sampled. At the end it
prints, and writes as one JSON line: good clients and how many failed,
hostile connections made, the RSS slope after warm-up (a least-squares fit,
KB a minute), descriptors at the end against the warm-up baseline, and the
checksum mismatches. Exit status 1 when a good client failed, a checksum
differed or descriptors did not come back.

usage: scripts/soak.py [--seconds S] [--json FILE]   (default 1800 s)
"""
import json
import os
import random
import re
import socket
import subprocess
import sys
import tempfile
import threading
import time

STOP_FULL = 0  # protocol/wire.h
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.path.join(ROOT, "build", "bin")


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def proc_figures(pid):
    rss = 0
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1])
    fds = len(os.listdir(f"/proc/{pid}/fd"))
    return rss, fds


def hello(model):
    """A HELLO for the whole stream of model (PROTOCOL.md), built by hand so
    the hostile clients need no library."""
    major = 7  # protocol/wire.h MTS_WIRE_MAJOR
    name = model.encode()
    body = b"MTSH" + major.to_bytes(2, "little") + (0).to_bytes(2, "little")
    body += bytes([len(name)]) + name  # string: varint length, bytes
    body += bytes([STOP_FULL, 0, 0])    # stop kind, stop value, resume batch (varints)
    body += (0).to_bytes(8, "little") + bytes([0])  # stream id, flags
    frame = bytes([1]) + body
    return len(frame).to_bytes(4, "little") + frame


def hostile(kind, port, model, stop, counts):
    """One hostile connection of the given kind; never raises."""
    try:
        s = socket.create_connection(("127.0.0.1", port), timeout=5)
        s.settimeout(5)
        if kind == "idle":  # connects and says nothing: the handshake timeout
            end = time.time() + 12
            while time.time() < end and not stop.is_set():
                time.sleep(0.5)
        elif kind == "trickle":  # a HELLO a byte a second
            for b in hello(model)[:8]:
                if stop.is_set():
                    break
                s.send(bytes([b]))
                time.sleep(1)
        elif kind == "garbage":
            s.send(os.urandom(random.randint(1, 4096)))
            time.sleep(0.2)
        elif kind == "reset":  # asks for the stream, reads a little, resets
            s.send(hello(model))
            s.recv(random.randint(1, 30000))
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        s.close()
        counts[kind] = counts.get(kind, 0) + 1
    except OSError:  # the server dropped it first (a slow handshake, garbage)
        counts[kind + "_dropped"] = counts.get(kind + "_dropped", 0) + 1


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       errors="replace")
    return p.returncode, p.stdout, p.stderr


def main():
    seconds = 1800
    json_path = None
    args = sys.argv[1:]
    while args:
        a = args.pop(0)
        if a == "--seconds":
            seconds = float(args.pop(0))
        elif a == "--json":
            json_path = args.pop(0)
        else:
            print(__doc__)
            return 2
    tmp = tempfile.mkdtemp(prefix="mts_soak_")
    models = os.path.join(tmp, "models")
    os.mkdir(models)
    names = ["cow"]
    rc, _, err = run([os.path.join(BIN, "mts-build"), os.path.join(ROOT, "tests/data/cow.off"),
                      "-o", os.path.join(models, "cow.mtsm"), "--quiet"])
    if rc != 0:
        print("soak: cannot build cow:", err)
        return 1
    bunny = os.path.join(ROOT, "..", "shared", "models", "bunny00.off")
    if os.path.exists(bunny):
        rc, _, err = run([os.path.join(BIN, "mts-build"), bunny, "-o",
                          os.path.join(models, "bunny00.mtsm"), "--quiet"])
        if rc == 0:
            names.append("bunny00")
    else:
        print("soak: ../shared/models/bunny00.off missing: cow only")
    port = free_port()
    log = open(os.path.join(tmp, "server.log"), "w")
    srv = subprocess.Popen([os.path.join(BIN, "mts-server"), "--models", models, "--listen",
                            f"127.0.0.1:{port}", "--workers", "2", "--quiet",
                            "--handshake-timeout", "5", "--idle-timeout", "10"],
                           stdout=subprocess.DEVNULL, stderr=log)
    for _ in range(200):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            break
        except OSError:
            time.sleep(0.05)
    time.sleep(2)  # the streams encoded

    # the unbroken run's checksum per model, for the resuming clients
    want = {}
    for m in names:
        rc, out, _ = run([os.path.join(BIN, "mts-client"), f"127.0.0.1:{port}", m, "--no-render",
                          "--json"])
        want[m] = json.loads(out).get("checksum") if rc == 0 else None

    stop = threading.Event()
    counts, samples = {}, []
    good = {"clients": 0, "failed": 0, "runs": 0, "checksum_mismatch": 0, "failures": []}

    def sampler():
        while not stop.is_set():
            try:
                samples.append((time.time(), *proc_figures(srv.pid)))
            except OSError:
                pass
            stop.wait(5)

    def hostile_loop():
        kinds = ["idle", "trickle", "garbage", "reset"]
        while not stop.is_set():
            ts = [threading.Thread(target=hostile, args=(k, port, random.choice(names), stop, counts))
                  for k in kinds for _ in range(3)]
            for t in ts:
                t.start()
            for t in ts:
                t.join()

    threads = [threading.Thread(target=sampler), threading.Thread(target=hostile_loop)]
    for t in threads:
        t.start()
    t0 = time.time()
    rounds = [
        ["--clients", "20"],
        ["--clients", "100", "--no-apply", "--verify"],
        ["--clients", "10", "--records"],
        ["--clients", "20", "--fraction", "0.3"],
    ]
    k = 0
    while time.time() - t0 < seconds:
        m = names[(k // len(rounds)) % len(names)]  # every round on every model
        extra = rounds[k % len(rounds)]
        rc, out, err = run([os.path.join(BIN, "mts-stress"), f"127.0.0.1:{port}", m, *extra,
                            "--json", "--quiet"])
        good["runs"] += 1
        try:
            j = json.loads(out)
            good["clients"] += j.get("clients", 0)
            good["failed"] += j.get("failed", 0)
            if j.get("failed"):
                good["failures"].append(j.get("failures"))
        except ValueError:
            good["failed"] += 1
            good["failures"].append(err[-300:])
        # a resuming client, whose final mesh must be the unbroken run's
        rc, out, err = run([os.path.join(BIN, "mts-client"), f"127.0.0.1:{port}", m,
                            "--no-render", "--json", "--resume"])
        good["clients"] += 1
        try:
            j = json.loads(out)
            if rc != 0:
                good["failed"] += 1
                good["failures"].append(j.get("error"))
            elif want.get(m) and j.get("checksum") != want[m]:
                good["checksum_mismatch"] += 1
        except ValueError:
            good["failed"] += 1
        k += 1
    stop.set()
    for t in threads:
        t.join()
    time.sleep(12)  # the hostile connections' timeouts run out
    rss_end, fds_end = proc_figures(srv.pid)
    srv.terminate()
    status = srv.wait(timeout=30)
    log.close()

    warm = [s for s in samples if s[0] - t0 >= min(120, seconds / 4)]
    slope = 0.0
    if len(warm) >= 3:
        xs = [(s[0] - warm[0][0]) / 60 for s in warm]
        ys = [s[1] for s in warm]
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        sxx = sum((x - mx) ** 2 for x in xs)
        slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx else 0.0
    fds_base = warm[0][2] if warm else (samples[0][2] if samples else 0)
    summary = {
        "seconds": round(time.time() - t0, 1),
        "models": names,
        "good_clients": good["clients"],
        "good_failed": good["failed"],
        "checksum_mismatch": good["checksum_mismatch"],
        "stress_runs": good["runs"],
        "hostile": counts,
        "rss_kb_first": samples[0][1] if samples else 0,
        "rss_kb_warm": warm[0][1] if warm else 0,
        "rss_kb_end": rss_end,
        "rss_slope_kb_per_min": round(slope, 1),
        "fds_warm": fds_base,
        "fds_end": fds_end,
        "server_exit": status,
        "failures": good["failures"][:5],
    }
    line = json.dumps(summary)
    print(line)
    if json_path:
        with open(json_path, "w") as f:
            f.write(line + "\n")
    ok = (good["failed"] == 0 and good["checksum_mismatch"] == 0 and fds_end <= fds_base
          and status == 0)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
