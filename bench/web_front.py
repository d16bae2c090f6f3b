#!/usr/bin/env python3
"""The page's web server under hostile load, for `make bench`.

nginx runs web/nginx.conf as `make demo-web` does (its three marked lines set
to loopback ports and a copy of the page folder, one process), in front of
mts-server --ws-listen. Measured, in one run:

  - nginx's resident memory idle, then with N clients (default 1,000) that
    each ask for the page's largest file and never read a byte;
  - then with M slow readers (default 100) of a 30 MB file, each taking
    1 KiB every 100 ms;
  - meanwhile, how long a good client takes to fetch the page (index.html,
    mts_web.js, mts_web.wasm), median of 5, in each of those states.

Prints a table and, with --json FILE, writes the figures there.
Usage: bench/web_front.py [--web-dir build/web] [--clients N] [--slow M]
                          [--big-mb 30] [--json FILE]
"""
import argparse
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def wait_port(port, seconds=30):
    end = time.time() + seconds
    while time.time() < end:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return True
        except OSError:
            time.sleep(0.05)
    return False


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def fetch(port, path, timeout=10):
    """One GET on its own connection; the body's size, or -1."""
    s = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    s.sendall(f"GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n".encode())
    data = bytearray()
    while True:
        chunk = s.recv(65536)
        if not chunk:
            break
        data += chunk
    s.close()
    head, _, body = bytes(data).partition(b"\r\n\r\n")
    return len(body) if head.startswith(b"HTTP/1.1 200") else -1


def page_ms(port, runs=5):
    """A good client's time for the page's three files, median of runs."""
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        ok = all(fetch(port, p) > 0 for p in ("/", "/mts_web.js", "/mts_web.wasm"))
        times.append((time.perf_counter() - t0) * 1e3 if ok else float("inf"))
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--web-dir", default=os.path.join(ROOT, "build/web"))
    ap.add_argument("--bin-dir", default=os.path.join(ROOT, "build/bin"))
    ap.add_argument("--clients", type=int, default=1000)
    ap.add_argument("--slow", type=int, default=100)
    ap.add_argument("--big-mb", type=int, default=30)
    ap.add_argument("--json")
    a = ap.parse_args()
    nginx = shutil.which("nginx") or next(
        (p for p in ("/usr/sbin/nginx", "/usr/local/sbin/nginx") if os.access(p, os.X_OK)), None)
    if not nginx:
        print("web_front: no nginx (scripts/deps.sh installs it)", file=sys.stderr)
        return 1
    if not os.path.exists(os.path.join(a.web_dir, "mts_web.wasm")):
        print(f"web_front: no {a.web_dir}/mts_web.wasm (make web)", file=sys.stderr)
        return 1
    tmp = tempfile.mkdtemp(prefix="mts_web_front.")
    procs = []
    try:
        root = os.path.join(tmp, "www")
        shutil.copytree(a.web_dir, root)
        largest = max(os.listdir(root), key=lambda n: os.path.getsize(os.path.join(root, n)))
        largest_bytes = os.path.getsize(os.path.join(root, largest))
        with open(os.path.join(root, "big.bin"), "wb") as f:
            block = os.urandom(1 << 20)
            for _ in range(a.big_mb):
                f.write(block)
        models = os.path.join(tmp, "models")
        os.mkdir(models)
        subprocess.run([os.path.join(a.bin_dir, "mts-build"), os.path.join(ROOT, "tests/data/cow.off"),
                        "-o", os.path.join(models, "cow.mtsm"), "--quiet"], check=True)
        ws_port, tcp_port, port = free_port(), free_port(), free_port()
        server = subprocess.Popen([os.path.join(a.bin_dir, "mts-server"), "--models", models,
                                   "--listen", f"127.0.0.1:{tcp_port}",
                                   "--ws-listen", f"127.0.0.1:{ws_port}", "--quiet"],
                                  stderr=subprocess.DEVNULL)
        procs.append(server)
        front = os.path.join(tmp, "front")
        os.mkdir(front)
        with open(os.path.join(ROOT, "web/nginx.conf")) as f:
            conf = f.read().splitlines()
        out = []
        for line in conf:
            body = line.lstrip()
            if not body.startswith("#") and "@LISTEN@" in line:
                line = f"        listen 127.0.0.1:{port} backlog=4096;"
            elif not body.startswith("#") and "@UPSTREAM@" in line:
                line = f"        server 127.0.0.1:{ws_port};"
            elif not body.startswith("#") and "@ROOT@" in line:
                line = f"        root {root};"
            out.append(line)
        with open(os.path.join(front, "nginx.conf"), "w") as f:
            f.write("\n".join(out) + "\n")
        ng = subprocess.Popen([nginx, "-p", front + "/", "-e", "stderr", "-c",
                               os.path.join(front, "nginx.conf"), "-g", "master_process off;"],
                              stdout=subprocess.DEVNULL, stderr=open(os.path.join(tmp, "nginx.err"), "w"))
        procs.append(ng)
        if not wait_port(port) or not wait_port(tcp_port):
            print("web_front: nginx or mts-server did not start: "
                  + open(os.path.join(tmp, "nginx.err")).read()[-500:], file=sys.stderr)
            return 1
        page_ms(port, 2)  # warm: the page cache, nginx's open-file state
        res = {"nginx": subprocess.run([nginx, "-v"], capture_output=True, text=True).stderr.strip(),
               "config": "web/nginx.conf (master_process off)",
               "largest_page_file": largest, "largest_page_file_bytes": largest_bytes,
               "idle_rss_mb": round(rss_mb(ng.pid), 1), "idle_page_ms": round(page_ms(port), 2)}

        # N clients ask for the largest file and never read
        req = f"GET /{largest} HTTP/1.1\r\nHost: x\r\n\r\n".encode()
        stalled = []
        for _ in range(a.clients):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.connect(("127.0.0.1", port))
            s.sendall(req)
            stalled.append(s)
        time.sleep(3)
        res["non_readers"] = a.clients
        res["non_readers_rss_mb"] = round(rss_mb(ng.pid), 1)
        res["non_readers_page_ms"] = round(page_ms(port), 2)
        for s in stalled:
            s.close()
        stalled = []
        time.sleep(1)

        # M slow readers of the big file
        stop = threading.Event()
        got = [0] * a.slow

        def slow_reader(k):
            s = socket.socket()
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            s.connect(("127.0.0.1", port))
            s.sendall(b"GET /big.bin HTTP/1.1\r\nHost: x\r\n\r\n")
            s.settimeout(1)
            while not stop.is_set():
                try:
                    chunk = s.recv(1024)
                except socket.timeout:
                    continue
                if not chunk:
                    break
                got[k] += len(chunk)
                time.sleep(0.1)
            s.close()

        threads = [threading.Thread(target=slow_reader, args=(k,)) for k in range(a.slow)]
        for t in threads:
            t.start()
        time.sleep(4)
        res["slow_readers"] = a.slow
        res["big_file_mb"] = a.big_mb
        res["slow_readers_rss_mb"] = round(rss_mb(ng.pid), 1)
        res["slow_readers_page_ms"] = round(page_ms(port), 2)
        t0 = time.perf_counter()
        res["good_client_big_file_ok"] = fetch(port, "/big.bin", timeout=60) == a.big_mb << 20
        res["good_client_big_file_ms"] = round((time.perf_counter() - t0) * 1e3, 1)
        stop.set()
        for t in threads:
            t.join()
        res["slow_readers_bytes_each_median"] = statistics.median(got)
        res["over_idle_mb_max"] = round(max(res["non_readers_rss_mb"], res["slow_readers_rss_mb"])
                                        - res["idle_rss_mb"], 1)
        print(f"\nThe page's web server (nginx, web/nginx.conf) under hostile load; {res['nginx']}")
        print(f"{'state':<44} {'nginx RSS MB':>12} {'page ms':>8}")
        print(f"{'idle':<44} {res['idle_rss_mb']:>12.1f} {res['idle_page_ms']:>8.2f}")
        print(f"{f'{a.clients} not reading {largest} ({largest_bytes // 1024} KB)':<44} "
              f"{res['non_readers_rss_mb']:>12.1f} {res['non_readers_page_ms']:>8.2f}")
        print(f"{f'{a.slow} reading {a.big_mb} MB at 10 KB/s':<44} "
              f"{res['slow_readers_rss_mb']:>12.1f} {res['slow_readers_page_ms']:>8.2f}")
        print(f"a good client's {a.big_mb} MB meanwhile: {res['good_client_big_file_ms']:.0f} ms "
              f"({'whole' if res['good_client_big_file_ok'] else 'FAILED'})")
        if a.json:
            with open(a.json, "w") as f:
                json.dump(res, f, indent=2)
                f.write("\n")
        return 0
    finally:
        for p in procs:
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
