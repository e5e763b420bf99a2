"""CNN speed: parameters, training time per epoch and inference latency per window, CPU (and CUDA).

Usage::

    .venv/bin/python bench/cnn_speed.py [--samples 256] [--batch 32] [--models cnn1d,cnn1d-lean,spectrum-cnn]
                                        [--devices cpu,cuda] [--repeats 3] [--json FILE]

For each network at its input length (cnn1d: the paper's 6400 points; cnn1d-lean: 4096 and 6400; spectrum-cnn:
4096) the script times, on random windows (timing does not depend on the values):

- ``epoch_s``: one training epoch over ``--samples`` windows in mini-batches of ``--batch`` (Adam,
  cross-entropy; the median of ``--repeats`` epochs after one warm-up epoch), and the same per 1000 windows;
- ``latency_ms``: inference of ONE window (batch 1, ``torch.no_grad``, eval mode), median of 20 calls;
- ``throughput``: windows per second at inference in batches of 256.

CUDA rows appear when a GPU is present (``torch.cuda.synchronize`` around every timed region).  Threads:
PyTorch's default (all cores).  The numbers go to stdout as a Markdown table; ``bench/HISTORY.md``
records them with the date and the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

import torch

CONFIGS = [("cnn1d", 6400), ("cnn1d-lean", 4096), ("cnn1d-lean", 6400), ("spectrum-cnn", 4096)]


def _sync(dev):
    if dev.type == "cuda":
        torch.cuda.synchronize()


def bench_one(arch: str, length: int, dev: torch.device, n: int, batch: int, repeats: int) -> dict:
    from rvdiag.models.cnn import build_network, count_parameters

    torch.manual_seed(0)
    net = build_network(arch, 6, length).to(dev)
    X = torch.randn(n, 1, length, device=dev)
    y = torch.randint(0, 6, (n,), device=dev)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    loss_fn = torch.nn.CrossEntropyLoss()

    def epoch():
        net.train()
        for s in range(0, n, batch):
            opt.zero_grad()
            loss_fn(net(X[s:s + batch]), y[s:s + batch]).backward()
            opt.step()

    epoch()  # warm-up
    times = []
    for _ in range(repeats):
        _sync(dev)
        t0 = time.perf_counter()
        epoch()
        _sync(dev)
        times.append(time.perf_counter() - t0)
    net.eval()
    lat = []
    with torch.no_grad():
        one = X[:1]
        net(one)
        for _ in range(20):
            _sync(dev)
            t0 = time.perf_counter()
            net(one)
            _sync(dev)
            lat.append(time.perf_counter() - t0)
        Xb = X[:256] if n >= 256 else X
        net(Xb)
        _sync(dev)
        t0 = time.perf_counter()
        net(Xb)
        _sync(dev)
        thr = len(Xb) / (time.perf_counter() - t0)
    ep = statistics.median(times)
    return {"model": arch, "input": length, "device": dev.type, "params": count_parameters(net),
            "epoch_s": ep, "epoch_s_per_1000": ep * 1000 / n, "latency_ms": 1e3 * statistics.median(lat),
            "throughput": thr}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--models", default="cnn1d,cnn1d-lean,spectrum-cnn")
    ap.add_argument("--devices", default="cpu,cuda")
    ap.add_argument("--json", default=None, help="also write the rows as JSON here")
    a = ap.parse_args(argv)
    models = set(a.models.split(","))
    devs = [torch.device(d) for d in a.devices.split(",") if d == "cpu" or torch.cuda.is_available()]
    rows = []
    print(f"torch {torch.__version__}, {torch.get_num_threads()} CPU threads, load average "
          f"{os.getloadavg()[0]:.1f}, {a.samples} windows per epoch, batch {a.batch}"
          + (f", GPU {torch.cuda.get_device_name(0)}" if torch.cuda.is_available() else ", no GPU"))
    print("| model | input | device | parameters | s / epoch | s / 1000 windows | latency ms / window | windows/s (batch 256) |")
    print("|---|---|---|---|---|---|---|---|")
    for dev in devs:
        for arch, length in CONFIGS:
            if arch not in models:
                continue
            r = bench_one(arch, length, dev, a.samples, a.batch, a.repeats)
            rows.append(r)
            print(f"| {arch} | {length} | {dev.type} | {r['params']:,} | {r['epoch_s']:.2f} | "
                  f"{r['epoch_s_per_1000']:.2f} | {r['latency_ms']:.2f} | {r['throughput']:.0f} |", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
