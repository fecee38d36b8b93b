#!/usr/bin/env python3
"""A bounded loopback load on `mobmap serve`, for scripts/tsan.sh: CLIENTS threads each
send REQUESTS mixed requests (light and heavy, good and refused) over keep-alive
connections, while TRICKLERS threads send requests a few bytes at a time (which the
server cuts off at its request timeout). Only 127.0.0.1 is ever contacted. It prints
what it sent and what came back, and exits 0 when every client has finished; the
answers' statuses are counted, not judged (a busy server may answer 503).

    python3 scripts/serve_load.py --port PORT [--clients 6] [--requests 40] [--tricklers 2]
"""
import argparse
import collections
import http.client
import json
import random
import socket
import threading
import time

LIGHT = [
    ("GET", "/api/info", None),
    ("GET", "/api/camera_path", None),
    ("GET", "/api/voxels?max=20000", None),
    ("GET", "/api/voxels?max=20000&offset=100&limit=500", None),
    ("POST", "/api/query", {"points": [[1.2, 0, 0.05], [2.0, 0.3, 0.0]], "snap": 0.3}),
    ("POST", "/api/foot", {"soles": [[1.2, 0, 0.05, 0, 0.25, 0.12]]}),
    ("POST", "/api/height_scan", {"poses": [[1.0, 0.0, 0.0, 0.0]]}),
    ("POST", "/api/query", {"points": [[1, 2]]}),  # refused: 400
    ("GET", "/api/nothing", None),  # 404
    ("GET", "/", None),
]
HEAVY = [
    ("GET", "/api/voxels?level=1", None),
    ("GET", "/api/voxels?level=2&limit=1000", None),
    ("GET", "/api/layer?max=20000", None),
    ("GET", "/api/layer?level=0&max=5000", None),
    ("POST", "/api/plan", {"from": [0.8, 0, 0.1], "to": [2.0, 0, 0.1], "time_limit_s": 20}),
    ("POST", "/api/query", {"points": [[1.2, 0, 0.05]], "reach": True}),
]


def client(port, requests, seed, counts, lock):
    rng = random.Random(seed)
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=600)
    for _ in range(requests):
        method, path, body = rng.choice(HEAVY if rng.random() < 0.25 else LIGHT)
        data = json.dumps(body).encode() if body is not None else None
        try:
            conn.request(method, path, body=data, headers={"Content-Type": "application/json", "Accept-Encoding": "gzip, br"})
            status = conn.getresponse()
            status.read()
            key = status.status
        except (OSError, http.client.HTTPException) as e:
            key = type(e).__name__
            conn.close()
            conn = http.client.HTTPConnection("127.0.0.1", port, timeout=600)
        with lock:
            counts[key] += 1
    conn.close()


def trickler(port, rounds, counts, lock):
    body = json.dumps({"points": [[1.2, 0, 0.05]]}).encode()
    request = (b"POST /api/query HTTP/1.1\r\nHost: load\r\nContent-Type: application/json\r\n"
               b"Content-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body)
    for _ in range(rounds):
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=600) as s:
                for i in range(0, len(request), 7):
                    s.sendall(request[i:i + 7])
                    time.sleep(0.05)  # load shape only: nothing waits on this
                s.recv(65536)
                key = "trickled"
        except OSError as e:
            key = "trickle " + type(e).__name__
        with lock:
            counts[key] += 1


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--clients", type=int, default=6)
    p.add_argument("--requests", type=int, default=40)
    p.add_argument("--tricklers", type=int, default=2)
    p.add_argument("--trickle-rounds", type=int, default=3)
    a = p.parse_args()
    counts, lock = collections.Counter(), threading.Lock()
    threads = [threading.Thread(target=client, args=(a.port, a.requests, i, counts, lock)) for i in range(a.clients)]
    threads += [threading.Thread(target=trickler, args=(a.port, a.trickle_rounds, counts, lock)) for _ in range(a.tricklers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print("serve_load: " + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items(), key=str)))


if __name__ == "__main__":
    main()
