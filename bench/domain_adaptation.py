"""Does unsupervised domain adaptation (skada) close the cross-speed gap of a classical model?

    .venv/bin/pip install skada==0.6.0        # not an rvdiag dependency: this script only (skorch==1.4.0 for --deep)
    .venv/bin/python bench/domain_adaptation.py SOURCE.zarr TARGET.zarr [TARGET.zarr ...] \
        [--features tsa-ci,spectrum] [--methods baseline,per-domain,coral,sa,kmm,linear-ot] [--deep]

Trains on the ``train`` split of SOURCE (e.g. the demo layout at 45 deg/s) and scores on each TARGET store
(another speed): features as ``rvdiag train --model svm --features NAME`` computes them (the same transformer and
its arguments, each window's speed from the store), then a standard scaler and an RBF SVC (C = 10, gamma
"scale"; rvdiag's svm less its Platt calibration, which does not change much the argmax and does not route through
skada's pipelines).  The adaptation sees the target's ``train`` split WITHOUT labels; accuracy is on the target's
``test`` split (held-out simulations), and the baseline's on SOURCE's own test split for reference.  Methods:

==========  =======================================================================================
baseline    no adaptation: scaler fitted on the source, SVC (what ``rvdiag train`` does); the methods
            below but per-domain start from the features so scaled
per-domain  each domain standardised by its own mean and deviation (skada ``PerDomain(StandardScaler())``)
coral       CORAL (Sun, Feng & Saenko 2017): source features whitened and recoloured to the target's
            covariance (skada ``CORALAdapter``, Ledoit-Wolf shrinkage)
sa          subspace alignment (Fernando et al. 2013; skada ``SubspaceAlignmentAdapter``, all components)
kmm         kernel mean matching (Huang et al. 2007): source samples reweighted to the target's kernel mean
            (skada ``KMMReweightAdapter``)
linear-ot   the linear optimal-transport (Gaussian) map between the domains (skada ``LinearOTMappingAdapter``)
mlp         (with ``--deep``) a two-hidden-layer MLP (64 ReLU units each) on the source only (skada ``SourceOnly``):
            the baseline of the two deep methods; Adam, lr 1e-3, 100 epochs, batches of 64, torch seed 0
deepcoral   the same MLP with the CORAL loss on its second hidden layer (Sun & Saenko 2016; skada ``DeepCoral``,
            reg 1)
dann        the same MLP with a domain classifier behind a gradient reversal layer (Ganin et al. 2016; skada
            ``DANN``, reg 1)
==========  =======================================================================================

Prints, per feature set, target and method, the accuracy and its ratio to the baseline's.  bench/HISTORY.md
("Domain adaptation (skada)") holds the figures.  Importing skada switches on scikit-learn's
metadata routing for the whole process (``sklearn.set_config(enable_metadata_routing=True)``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

METHODS = ("baseline", "per-domain", "coral", "sa", "kmm", "linear-ot")
#: The deep methods (skada.deep, which also needs skorch): a small MLP on the standardised features.
DEEP = ("mlp", "deepcoral", "dann")


def features(store, split: str, name: str, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(features, labels) of a split, computed as ``rvdiag train --model svm --features NAME`` would."""
    from rvdiag.workflows.training import build_estimator
    from rvdiag.features.combine import input_metadata, with_metadata

    est = build_estimator("svm", name, seed=seed, epochs=1, device="cpu", batch_size=32, lr=1e-3,
                          input_length=None, patience=1, validation_fraction=0.2, fs=store.fs)
    s = store.load(split)
    X = with_metadata(s.X, s.meta, input_metadata(est), where="the store")
    return np.asarray(est.steps[0][1].fit(X, s.y).transform(X), dtype=float), np.asarray(s.y).astype(str)


def _mlp(n_in: int, n_classes: int, hidden: int = 64):
    import torch

    class MLP(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.dense0, self.act0 = torch.nn.Linear(n_in, hidden), torch.nn.ReLU()
            self.dense1, self.act1 = torch.nn.Linear(hidden, hidden), torch.nn.ReLU()
            self.out = torch.nn.Linear(hidden, n_classes)

        def forward(self, X, sample_weight=None):
            return self.out(self.act1(self.dense1(self.act0(self.dense0(X)))))

    return MLP()


def deep_method(name: str, n_in: int, n_classes: int, seed: int = 0):
    """An unfitted skada.deep estimator for a method of :data:`DEEP`."""
    import torch
    from skada.deep import DANN, DeepCoral, SourceOnly

    torch.set_num_threads(1)  # a tiny MLP: more threads only contend
    torch.manual_seed(seed)
    kw = {"max_epochs": 100, "batch_size": 64, "optimizer": torch.optim.Adam, "lr": 1e-3, "train_split": None,
          "verbose": 0}
    module = _mlp(n_in, n_classes)
    if name == "mlp":
        return SourceOnly(module, **kw)
    if name == "deepcoral":
        return DeepCoral(module, layer_name="act1", reg=1, **kw)
    if name == "dann":
        return DANN(module, layer_name="act1", reg=1, num_features=64, **kw)
    raise SystemExit(f"unknown method {name!r}; use one of {','.join(DEEP)}")


def method(name: str, seed: int = 0):
    """An unfitted skada pipeline (or a plain one for the baseline) for a method name."""
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    svc = SVC(C=10.0, gamma="scale", random_state=seed)
    if name == "baseline":
        return make_pipeline(StandardScaler(), svc)
    from skada import (CORALAdapter, KMMReweightAdapter, LinearOTMappingAdapter, PerDomain,
                       SubspaceAlignmentAdapter, make_da_pipeline)

    # the other methods get features already standardised with the source's mean and deviation (run())
    if name == "per-domain":
        return make_da_pipeline(PerDomain(StandardScaler()), svc)
    if name == "coral":
        return make_da_pipeline(CORALAdapter(reg="auto"), svc)
    if name == "sa":
        return make_da_pipeline(SubspaceAlignmentAdapter(n_components=None, random_state=seed), svc)
    if name == "kmm":
        return make_da_pipeline(KMMReweightAdapter(gamma=None), svc.set_fit_request(sample_weight=True))
    if name == "linear-ot":
        return make_da_pipeline(LinearOTMappingAdapter(), svc)
    raise SystemExit(f"unknown method {name!r}; use one of {','.join(METHODS)}")


def run(source: str, targets: list[str], feature_sets: list[str], methods: list[str]) -> None:
    from sklearn.preprocessing import StandardScaler

    from rvdiag.datasets import SampleStore

    src = SampleStore.open(source)
    classes = sorted(set(src.classes))
    code = {c: i for i, c in enumerate(classes)}
    for fname in feature_sets:
        t0 = time.perf_counter()
        Xs, ys = features(src, "train", fname)
        Xs_test, ys_test = features(src, "test", fname)
        tgt = {}
        for p in targets:
            st = SampleStore.open(p)
            tgt[p] = (features(st, "train", fname)[0], *features(st, "test", fname))
        print(f"features {fname}: {Xs.shape[1]} per sample, {time.perf_counter() - t0:.0f} s; source "
              f"{source} {len(ys)} train / {len(ys_test)} test samples", flush=True)
        ys_i = np.array([code[c] for c in ys])
        sc = StandardScaler().fit(Xs)  # the baseline's scaling, fitted on the source
        scaled = {p: tuple(sc.transform(a) for a in (Xs, Xt_train, Xt_test, Xs_test))
                  for p, (Xt_train, Xt_test, _) in tgt.items()}
        base = {}
        for p, (Xt_train, Xt_test, yt_test) in tgt.items():
            yt_i = np.array([code[c] for c in yt_test])
            for m in methods:
                t0 = time.perf_counter()
                pipe = deep_method(m, Xs.shape[1], len(classes)) if m in DEEP else method(m)
                if m == "baseline":
                    pipe.fit(Xs, ys_i)
                    pred, pred_src = pipe.predict(Xt_test), pipe.predict(Xs_test)
                else:
                    S, T, Tt, St = (Xs, Xt_train, Xt_test, Xs_test) if m == "per-domain" else scaled[p]
                    X = np.vstack([S, T])
                    y = np.concatenate([ys_i, -np.ones(len(T), dtype=int)])
                    sd = np.concatenate([np.ones(len(S), dtype=int), -2 * np.ones(len(T), dtype=int)])
                    if m in DEEP:  # skorch wants float32 inputs
                        X, Tt = X.astype(np.float32), Tt.astype(np.float32)
                    pipe.fit(X, y, sample_domain=sd)
                    pred = np.asarray(pipe.predict(Tt, sample_domain=-2 * np.ones(len(Tt), dtype=int)))
                    pred_src = None  # an adapter maps the source to the target: no source score
                acc = float(np.mean(pred == yt_i))
                src_txt = "" if pred_src is None else \
                    f"  source test {100 * np.mean(pred_src == np.array([code[c] for c in ys_test])):5.1f} %"
                if m == "baseline":
                    base[p] = acc
                recall = " / ".join(f"{100 * np.mean(pred[yt_i == k] == k):.0f}" for k in range(len(classes)))
                ratio = acc / base[p] if base.get(p) else float("nan")
                print(f"  {fname:10s} {p.rsplit('/', 1)[-1]:12s} {m:11s} accuracy {100 * acc:5.1f} %  "
                      f"ratio {ratio:4.2f}  recall {recall} %{src_txt}  "
                      f"({time.perf_counter() - t0:.1f} s)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source")
    ap.add_argument("targets", nargs="+")
    ap.add_argument("--features", default="tsa-ci,spectrum")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--deep", action="store_true", help="also " + ", ".join(DEEP) + " (skada.deep: torch + skorch)")
    a = ap.parse_args()
    run(a.source, a.targets, a.features.split(","), a.methods.split(",") + (list(DEEP) if a.deep else []))


if __name__ == "__main__":
    main()
