"""Accuracy against SNR: one model per noise level, trained and tested on a library with that noise added.

    python examples/snr_curve.py out/demo.zarr --levels=-5,0,5,10,15,20 --out out/snr

For each level L this runs ``rvdiag train STORE --snr-db L ...``: white Gaussian noise at L dB below each
sample's power is added (seeded) to the training and the test samples of the store, and the model is trained
on the one and scored on the other.  The store should be (nearly) clean -- the demo library is at 40 dB, so
the effective SNR is within 0.05 dB of L up to 20 dB.  Writes ``snr_curve.json`` (accuracy, macro F1, kappa
and per-class recall per level, and the commands) and ``snr_curve.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

RVDIAG = [sys.executable, "-m", "rvdiag"]
DEFAULT_TRAIN = ["--model", "cnn1d-lean", "--representation", "logspec", "--epochs", "40", "--lr", "3e-3",
                 "--patience", "6", "--seed", "0"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store", type=Path)
    ap.add_argument("--levels", default="-5,0,5,10,15,20", help="SNRs in dB, comma-separated")
    ap.add_argument("--out", type=Path, default=Path("out/snr"))
    ap.epilog = f"Any other option goes to rvdiag train (default: {' '.join(DEFAULT_TRAIN)})."
    args, train_options = ap.parse_known_args()
    levels = [float(x) for x in args.levels.split(",") if x.strip()]
    options = [o for o in train_options if o != "--"] or DEFAULT_TRAIN
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for level in levels:
        cmd = ["train", str(args.store), "--out", str(args.out / f"model_{level:g}dB"), "--snr-db", f"{level:g}",
               "--json", *options]
        print("$ rvdiag " + " ".join(cmd), flush=True)
        proc = subprocess.run([*RVDIAG, *cmd], stdout=subprocess.PIPE, text=True)
        if proc.returncode != 0:
            sys.exit(proc.returncode)
        m = json.loads(proc.stdout)["metrics"]
        rows.append({"snr_db": level, "accuracy": m["accuracy"], "f1_macro": m["f1_macro"], "kappa": m["kappa"],
                     "recall": {c: v["recall"] for c, v in m["per_class"].items()}, "command": "rvdiag " + " ".join(cmd)})
        print(f"   {level:g} dB: accuracy {100 * m['accuracy']:.2f} %", flush=True)
    (args.out / "snr_curve.json").write_text(json.dumps(rows, indent=2))
    _plot(rows, args.out / "snr_curve.png")
    print(f"wrote {args.out / 'snr_curve.json'} and {args.out / 'snr_curve.png'}")


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = [r["snr_db"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(x, [100 * r["accuracy"] for r in rows], "k-o", lw=2, label="overall")
    for c in rows[0]["recall"]:
        ax.plot(x, [100 * r["recall"][c] for r in rows], "--", lw=1, label=c)
    ax.set_xlabel("SNR (dB)")
    ax.set_ylabel("test accuracy / recall (%)")
    ax.set_ylim(0, 102)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
