"""``rvdiag simulate``: simulate the housing vibration of the reducer in a fault state, write an .npz."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import ParameterError

#: Python parameters of :func:`rvdiag.dynamics.simulate` and :class:`~rvdiag.dynamics.ModelSettings` -> options.
SIMULATE_OPTION_NAMES = {"duration_s": "--duration", "fs": "--fs", "substeps": "--substeps",
                         "transient_s": "--transient", "segment_s": "--segment", "workers": "--workers",
                         "noise_snr_db": "--snr-db", "load_Nm": "--load", "input_speed_rpm": "--input-speed",
                         "output_speed_deg_s": "--output-speed", "signal": "--signal",
                         "current_fs": "--current-fs", "current_snr_db": "--current-snr-db",
                         "load_inertia_kg_m2": "--load-inertia"}


def _check_severities(state: str, severities: dict) -> None:
    """Validate every given severity and refuse one the state does not use (it would be ignored)."""
    from rvdiag.gears import BrokenTooth, Pitting, RootCrack, Spalling, Wear
    from rvdiag.gears.faults import FAULT_KINDS as STATES

    kinds = STATES.get(state, "").split("+")
    for key in severities:
        if opt.FAULT_SEVERITY_OPTIONS[key].kind not in kinds:
            raise ParameterError(f"{opt.FAULT_SEVERITY_OPTIONS[key].option} does not apply to state {state} ({STATES.get(state, '?')})")
    if "wear_depth" in severities:
        Wear(severities["wear_depth"])
    if "crack_depth" in severities or "crack_angle_deg" in severities:
        RootCrack(severities.get("crack_depth", 0.0), severities.get("crack_angle_deg", 45.0))
    if "broken_fraction" in severities:
        BrokenTooth(severities["broken_fraction"])
    pits = {k: severities[key] for k, key in (("area_fraction", "pit_area_fraction"), ("radius", "pit_radius"),
                                              ("depth", "pit_depth")) if key in severities}
    if pits:
        Pitting(**pits)
    spall = {k: severities[key] for k, key in (("width_fraction", "spall_width_fraction"),
                                               ("length_fraction", "spall_length_fraction"),
                                               ("depth", "spall_depth")) if key in severities}
    if spall:
        Spalling(**spall)


#: the most output torque ``--load`` takes, as a multiple of the parameter set's rated torque: the momentary
#: maximum (emergency-stop) torque of the RV-E series is about 5x rated (RV-20E: 833 N m against 167 N m rated,
#: Nabtesco RV-E catalog); beyond it the reducer would break, not vibrate.
MAX_LOAD_X_RATED = 5.0


def _check_load(load: float | None, params) -> None:
    """Refuse a ``--load`` beyond :data:`MAX_LOAD_X_RATED` times the rated torque (a typo such as 99999)."""
    rated = params.operation.rated_torque
    if load is not None and abs(load) > MAX_LOAD_X_RATED * rated:
        raise ParameterError(f"--load {load:g} N m is {abs(load) / rated:.0f}x the rated torque {rated:g} N m of the "
                             f"parameter set; the reducer's momentary maximum is about {MAX_LOAD_X_RATED:g}x rated: "
                             f"give at most {MAX_LOAD_X_RATED * rated:g} N m")


def _rates(signal: str, fs: float | None, current_fs: float | None) -> tuple[float, float]:
    """(integration rate, current rate).  With ``--signal current`` the record is the current, so ``--fs`` is its
    rate, as a servo engineer reads it (a drive logs its currents at 1-10 kHz); the model is then integrated at
    the default 48 kHz.  Giving both --fs and --current-fs there is ambiguous and refused."""
    if signal == "current" and fs is not None:
        if current_fs is not None and current_fs != fs:
            raise ParameterError("with --signal current, --fs is the current's sampling rate: give --fs or "
                                 "--current-fs, not both")
        return 48000.0, fs
    return (48000.0 if fs is None else fs), (1000.0 if current_fs is None else current_fs)


def register(app: typer.Typer) -> None:
    """Add the ``simulate`` command to ``app``."""

    from rvdiag.gears.faults import FAULT_KINDS as STATES

    states_help = ", ".join(f"{k} {v}" for k, v in STATES.items())

    @app.command("simulate")
    @opt.fault_severity_options
    def simulate_cmd(
        state: str = typer.Option("T1", "--state", help=f"Fault state: {states_help}."),
        severities: Optional[dict] = None,  # the ten fault-severity options (opt.fault_severity_options)
        params: Optional[Path] = opt.params(),
        pin_wear_depth: Optional[float] = typer.Option(None, "--pin-wear-depth", help="Wear of the cycloid-pin "
                                                       "stage, with any --state: the largest clearance growth along "
                                                       "a pin's contact normal on each flank (mm, 0 to 0.1; Archard's "
                                                       "shape; default: the parameter set's [stage2] pin_wear_depth)."),
        input_speed: Optional[float] = typer.Option(None, "--input-speed", help="Motor (sun) speed, rpm."),
        output_speed: Optional[float] = typer.Option(None, "--output-speed", help="Output (carrier) speed, deg/s."),
        load: Optional[float] = typer.Option(None, "--load", help="Output load torque, N m (default: rated torque)."),
        duration: float = typer.Option(1.0, "--duration", help="Recorded signal length, s (after the transient)."),
        fs: Optional[float] = opt.fs("Sampling rate, Hz (default 48000); with --signal current, the current's "
                                     "rate (as --current-fs; the model is then integrated at 48000 Hz)."),
        snr_db: Optional[float] = opt.snr_db("Add white Gaussian noise at this SNR (dB)."),
        noise_snr: Optional[float] = opt.deprecated("--noise-snr"),
        seed: int = opt.seed("Seed of the noise."),
        substeps: int = typer.Option(9, "--substeps", help="Integrator steps per output sample (Kutta's 3/8 rule; "
                                     "default as ModelSettings: 9, within 1e-3 of scipy's DOP853 up to 4500 rpm at "
                                     "48 kHz)."),
        transient: Optional[float] = typer.Option(None, "--transient", help="Discarded start-up time, s (default: "
                                                  "the model's, 0.1 s; library configs default to the same)."),
        workers: int = typer.Option(1, "--workers", help="Time segments integrated at once (threads); the "
                                    "signal does not depend on it."),
        segment: Optional[float] = typer.Option(None, "--segment", help="Cut the record into segments of this "
                                                "many seconds, each started --transient ahead and integrated "
                                                "on its own (0: one continuous run; default 0, or 1 s with "
                                                "--workers > 1)."),
        profile: str = typer.Option("constant", "--profile", help="Output speed profile: constant, trapezoid "
                                    "(from rest at --accel to --output-speed, cruise, decelerate to rest at the "
                                    "record's end) or scurve (the same with the jerk limited to --jerk: speed and "
                                    "acceleration continuous)."),
        accel: Optional[float] = typer.Option(None, "--accel", help="Trapezoid's or S-curve's acceleration and "
                                              "deceleration (limit), deg/s^2."),
        jerk: Optional[float] = typer.Option(None, "--jerk", help="S-curve's jerk limit, deg/s^3."),
        arm_mass: float = typer.Option(0.0, "--arm-mass", help="Gravity arm on the output: point mass, kg "
                                       "(load T0 + M g L cos(angle); its inertia M L^2 the load DOF's unless --load-inertia says otherwise)."),
        arm_length: float = typer.Option(0.0, "--arm-length", help="Gravity arm's length, m."),
        arm_angle: float = typer.Option(0.0, "--arm-angle", help="Gravity arm's angle above the horizontal at the "
                                        "record's start, deg."),
        load_inertia: Optional[float] = typer.Option(None, "--load-inertia", help="The load's polar inertia on the "
                                                     "output coupling, kg m^2: a DOF of the model (0: a pure load "
                                                     "torque; default: the parameter set's [operation] load_inertia, "
                                                     "else the gravity arm's M L^2)."),
        signal: str = typer.Option("vibration", "--signal", help="What to record: vibration (housing "
                                   "acceleration), current (the servo motor's phase currents i_a, i_b, i_c, i_q and "
                                   "its speed, from the PMSM model under i_d = 0 vector control) or both."),
        current_fs: Optional[float] = typer.Option(None, "--current-fs", help="Sampling rate of the motor "
                                                   "current, Hz (default 1000; a simple fraction of the integration "
                                                   "rate --fs, 48000 Hz with --signal current)."),
        current_snr_db: Optional[float] = typer.Option(None, "--current-snr-db", help="More white noise on the "
                                                       "current at this SNR (dB), beyond the sensors' own."),
        out: Path = opt.out("Output .npz (signal, fs, settings; with --signal both also current, current_fs)."),
        overwrite: bool = opt.overwrite("Replace an existing --out file."),
        quiet: bool = opt.quiet(),
    ) -> None:
        """Simulate the housing acceleration (x, y) of the reducer and, with --signal current or both, the servo
        motor's phase currents; write signal, fs and settings (and the current) to an .npz."""
        from rvdiag.dynamics import ModelSettings, simulate
        from rvdiag.gears import ToothFaults
        from rvdiag.params import ReducerParams

        if input_speed is not None and output_speed is not None:
            raise ParameterError("give either --input-speed or --output-speed, not both")
        if input_speed is None and output_speed is None:
            raise ParameterError("give --input-speed RPM or --output-speed DEG_S")
        if out.suffix != ".npz":
            raise ParameterError(f"--out must name a .npz file, got {out}")
        if not out.parent.exists():
            raise ParameterError(f"--out directory does not exist: {out.parent}")
        opt.refuse_existing(out, overwrite)
        fault = ToothFaults.for_state(state, **severities)
        _check_severities(fault.label or state.upper(), severities)
        if workers < 1:
            raise ParameterError(f"--workers must be >= 1, got {workers}")
        snr_db = opt.resolve(snr_db, noise_snr, "--noise-snr")
        p = ReducerParams.load(params)
        if pin_wear_depth is not None:
            from rvdiag.gears.pin_wear import check_pin_wear_depth

            depth = check_pin_wear_depth(pin_wear_depth * 1e-3, "--pin-wear-depth", scale=1e-3, unit="mm")
            p = p.replace(stage2={"pin_wear_depth": depth})
        fs, current_fs = _rates(signal, fs, current_fs)
        _check_load(load, p)
        if segment is None:
            segment = 1.0 if workers > 1 else 0.0
        with opt.option_names(SIMULATE_OPTION_NAMES):
            settings = ModelSettings(substeps=substeps, segment_s=segment,
                                     **({} if transient is None else {"transient_s": transient}))
        from rvdiag.dynamics import LoadProfile, SpeedProfile

        if profile not in ("constant", "trapezoid", "scurve"):
            raise ParameterError(f"--profile must be constant, trapezoid or scurve, got {profile!r}")
        if jerk is not None and profile != "scurve":
            raise ParameterError("--jerk needs --profile scurve")
        if profile == "trapezoid":
            if output_speed is None or accel is None:
                raise ParameterError("--profile trapezoid needs --output-speed DEG_S and --accel DEG_S2")
            speed_profile = SpeedProfile("trapezoid", output_speed, accel)
            speed_profile.validate(duration)
        elif profile == "scurve":
            if output_speed is None or accel is None or jerk is None:
                raise ParameterError("--profile scurve needs --output-speed DEG_S, --accel DEG_S2 and --jerk DEG_S3")
            speed_profile = SpeedProfile("scurve", output_speed, accel, jerk_deg_s3=jerk)
            speed_profile.validate(duration)
        elif accel is not None:
            raise ParameterError("--accel needs --profile trapezoid or scurve")
        else:
            speed_profile = SpeedProfile()
        load_profile = LoadProfile(arm_mass, arm_length, arm_angle)
        load_profile.validate()
        kw = dict(input_speed_rpm=input_speed, output_speed_deg_s=output_speed, load_Nm=load,
                  profile=speed_profile, load_profile=load_profile,
                  duration_s=duration, fs=fs, noise_snr_db=snr_db, seed=seed, settings=settings,
                  workers=workers, signal=signal, current_fs=current_fs, current_snr_db=current_snr_db,
                  load_inertia_kg_m2=load_inertia)
        with opt.option_names(SIMULATE_OPTION_NAMES):
            if quiet:
                res = simulate(p, None if fault.is_healthy else fault, **kw)
            else:
                from rich.progress import Progress, TextColumn, TimeRemainingColumn

                from rvdiag.cli._progress import bar_columns, stderr_console

                with Progress(*bar_columns()[:2], TextColumn("{task.percentage:>3.0f}%"), TextColumn("ETA"),
                              TimeRemainingColumn(), transient=True, console=stderr_console()) as bar:
                    task = bar.add_task("simulating", total=None)

                    def progress(done: int, total: int) -> None:
                        bar.update(task, completed=done, total=total)

                    res = simulate(p, None if fault.is_healthy else fault, progress=progress, **kw)
        res.settings["state"] = state.upper()
        res.settings["severities_SI"] = severities
        res.settings["params_file"] = str(params) if params is not None else None
        try:
            res.to_npz(out)
        except OSError as exc:
            raise ParameterError(f"cannot write --out {out}: {exc}") from None
        typer.echo(f"wrote {out}: {res.signal.shape[0]} channels x {res.signal.shape[1]} samples at {res.fs:g} Hz")
        if signal == "both":
            typer.echo(f"  and the motor current: {', '.join(res.current_names)} x {res.current.shape[1]} samples "
                       f"at {res.current_fs:g} Hz")
