"""Shared test helpers: where the public measured data sets are, and how a test that needs them skips.

The real-data tests read two public data sets that do not ship with rvdiag (docs/real-data.md, "Getting the
data"). They look for them in ``$RVDIAG_DATA_DIR``, else in a ``shared/data`` folder beside the checkout (the
layout of the development machines), and run wherever the files are; elsewhere they skip with a reason that
says where to get each file and its SHA-256.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: where each data set comes from
SOURCES = {
    "spectraquest-gearbox": "SpectraQuest Gearbox Fault Diagnostics Simulator data, 'Gearbox Fault Diagnosis Data' "
                            "on OpenEI (NREL data submission 623; also on Kaggle), CSV files gzipped",
    "cwru-bearing": "Case Western Reserve University Bearing Data Center, 12 kHz drive-end MAT files "
                    "(normal_<load>, B/IR/OR<size>@6_<load>)",
}

#: SHA-256 of every file a test reads
SHA256 = {
    "spectraquest-gearbox/h30hz0.csv.gz": "076e997257fb6b2599d34f0cd5d8c3242d8040dda3a74116c9bcf0e87c084af8",
    "spectraquest-gearbox/h30hz60.csv.gz": "8fcb6b862eae5eb91b19b8f48e3914839622e20eed59f3604359cdabb99ae479",
    "spectraquest-gearbox/b30hz0.csv.gz": "992eeae01ed9768b54e428eda9125d8895e54dfe416db2d744206a2ac5fbaaa9",
    "spectraquest-gearbox/b30hz60.csv.gz": "8c6b79f90d2bff439cb6d5c1e952c123c8d8a5b1e1933dd23642c1975253b6c8",
    "cwru-bearing/normal_0.mat": "16bf48babcf1c7ac224bc1a81cd9eafdb27e42d5cf559761907e067e8eeadf3c",
    "cwru-bearing/IR007_0.mat": "f80b0ea04fd06b372a0eaec7c056543ea37e4bb4727a5b173d2a5bacd2aa9cab",
    "cwru-bearing/OR007@6_0.mat": "35a095307d0971477049b343a1b5981dde465a58fb7f233ad89b035068c1717d",
    "cwru-bearing/OR021@6_0.mat": "ebcbdb96612e8085bbdbf81f0e5e8e8a8d1a693d1ec559c4894f7792771aa9b2",
}


def real_data_dir() -> Path:
    """The folder holding the measured data sets: ``$RVDIAG_DATA_DIR``, else ``shared/data`` beside the checkout."""
    env = os.environ.get("RVDIAG_DATA_DIR")
    return Path(env) if env else REPO.parent / "shared" / "data"


DATA = real_data_dir()


def missing_reason(files: tuple[str, ...], data: Path | None = None) -> str | None:
    """Why the tests on ``files`` (paths relative to the data folder) cannot run, or ``None`` when they can."""
    data = DATA if data is None else data
    missing = [f for f in files if not (data / f).is_file()]
    if not missing:
        return None
    wanted = "; ".join(f"{f} from {SOURCES[f.split('/')[0]]}, sha256 {SHA256[f]}" for f in missing)
    return (f"measured data not found in {data} (set RVDIAG_DATA_DIR to the folder that holds it); get {wanted} "
            "(docs/real-data.md, 'Getting the data')")


def needs_real_data(*files: str):
    """A ``skipif`` mark for a test that reads ``files`` of the measured data sets."""
    unknown = [f for f in files if f not in SHA256]
    assert not unknown, f"add the SHA-256 of {unknown} to tests/conftest.py"
    reason = missing_reason(files)
    return pytest.mark.skipif(reason is not None, reason=reason or "")


def run_cli(argv: list, capsys) -> tuple[int, str, str]:
    """Run ``rvdiag ARGV`` in this process: (exit code, stdout, stderr)."""
    from rvdiag.cli import main

    try:
        main([str(a) for a in argv])
        code = 0
    except SystemExit as exc:
        code = 0 if exc.code is None else exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def as_saved_before_a_move(model_dir, new_module: str, old_module: str) -> None:
    """Rewrite ``model_dir/model.skops`` as rvdiag wrote it when the types of ``new_module`` lived in
    ``old_module`` (the module names in its ``schema.json``; the arrays are copied unchanged)."""
    import io
    import zipfile

    f = Path(model_dir) / "model.skops"
    src, out = zipfile.ZipFile(io.BytesIO(f.read_bytes())), io.BytesIO()
    with zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            body = src.read(info)
            if info.filename == "schema.json":
                assert f'"{new_module}"'.encode() in body
                body = body.replace(f'"{new_module}"'.encode(), f'"{old_module}"'.encode())
            dst.writestr(info, body)
    f.write_bytes(out.getvalue())


def potential_gradient(model, t: float, q):
    """Central-difference gradient of :func:`rvdiag.dynamics.linear.potential_energy` at ``(t, q)``, the check
    that the compiled forces are ``Q = -grad V``.  Steps of 1e-12 (1e-13 on rotations, every third coordinate) are
    small enough that no pin contact changes state within one."""
    import numpy as np

    from rvdiag.dynamics.linear import potential_energy

    grad = np.empty(model.n_dof)
    for i in range(model.n_dof):
        h = 1e-13 if i % 3 == 2 else 1e-12
        dq = np.zeros(model.n_dof)
        dq[i] = h
        grad[i] = (potential_energy(model, t, q + dq) - potential_energy(model, t, q - dq)) / (2 * h)
    return grad


def assert_forces_are_minus_gradient(model, other, t: float, rng, rtol: float = 1e-6) -> None:
    """At the static solution of ``model`` at ``t`` plus a 1e-8 m/rad jitter (velocities 0): M a of the compiled
    kernels equals -:func:`potential_gradient` of the NumPy potential within ``rtol`` of its largest entry (the
    central differences' rounding is 3e-7 to 1.1e-6 of it), and differs from ``other``'s (a model without the term
    under test) by more than 1 %, so that the comparison can fail."""
    import numpy as np

    from rvdiag.dynamics import model as mdl
    from rvdiag.dynamics.linear import static_equilibrium

    q = static_equilibrium(model, t) + 1e-8 * rng.standard_normal(model.n_dof)
    y = np.concatenate([q, np.zeros_like(q)])
    Ma = mdl.make_rhs(model)(t, y)[model.n_dof:] * model.mass
    Ma_other = mdl.make_rhs(other)(t, y)[model.n_dof:] * model.mass
    assert np.max(np.abs(Ma - Ma_other)) > 1e-2 * np.max(np.abs(Ma))
    np.testing.assert_allclose(Ma, -potential_gradient(model, t, q), rtol=0, atol=rtol * np.max(np.abs(Ma)))


#: The relative spread (of the largest absolute value) that a simulation may show between two x86-64 CPUs.  numba
#: compiles for the host CPU (vector width, FMA contraction), so the last bits of a stored array are those of the
#: machine that wrote it.  Measured on the golden signals of tests/golden/before_manufacturing_errors.npz: 1.7e-13
#: between this machine's native target (AMD EPYC, AVX-512) and ``NUMBA_CPU_NAME=generic`` (no AVX, no FMA);
#: 1.9e-13 between the kernels' two compiled copies (with and without the manufacturing errors' terms) in one run.
#: 1e-10 leaves a margin of ~500x; any change of the model moves these signals by more than 1e-3 (each test
#: that uses this bound also shows that).
CROSS_CPU_RTOL = 1e-10


def assert_close_across_cpus(actual, expected) -> None:
    """``actual`` equals ``expected`` (e.g. a stored golden array) within :data:`CROSS_CPU_RTOL` of its largest
    absolute value: the same model on any x86-64 CPU."""
    import numpy as np

    actual, expected = np.asarray(actual), np.asarray(expected)
    assert actual.shape == expected.shape
    scale = float(np.max(np.abs(expected)))
    np.testing.assert_allclose(actual, expected, rtol=0, atol=CROSS_CPU_RTOL * scale)
