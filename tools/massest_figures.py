"""Print the mass-estimation reproduction figures (docs/machines/machining-centre.md):
estimator errors on the seeded synthetic recordings, the calibration's effect, and the
thesis's wrong formulas.

    .venv/bin/python tools/massest_figures.py [--seeds 10]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from softplc.machines.machining import estimator, synth, thesis
from softplc.machines.machining.settings import thesis_settings


def err(sc: synth.Scenario, s=None, calibrate: bool = True) -> float:
    s = s or thesis_settings()
    cal, meas = synth.recordings(sc)
    if not calibrate:
        return estimator.estimate_traces(estimator.to_trace(meas, s), None, s).mass / sc.mass - 1
    return estimator.estimate(meas, cal, s).mass / sc.mass - 1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    n = ap.parse_args().seeds
    s = thesis_settings()
    ref = synth.Scenario()
    print(f"reference scenario, m = {ref.mass:g} kg")
    print(f"  noise-free:                 {err(ref.without_noise()):+.4%}")
    noisy = [err(replace(ref, seed=k)) for k in range(n)]
    print(f"  reference noise, {n} seeds:  {min(noisy):+.3%} .. {max(noisy):+.3%}")
    print(f"  no calibration (F_pos on):  {err(ref.without_noise(), calibrate=False):+.3%}")
    nopos = replace(ref, pos_force=(0.0, 0.0)).without_noise()
    print(f"  F_pos = 0, no calibration:  {err(nopos, calibrate=False):+.4%}")
    mac, ms = synth.macro_scenario(), synth.macro_settings()
    print(f"macro geometry (triangle), noise-free: {err(mac.without_noise(), ms):+.4%}, "
          f"noisy: {err(mac, ms):+.3%}")
    for jerk in (10.0, 1.0):
        sc = replace(ref, measurement=replace(ref.measurement, jerk=jerk)).without_noise()
        print(f"S-curve jerk {jerk:g} m/s³, noise-free: {err(sc):+.4%}")
    cal, meas = synth.recordings(ref.without_noise())
    est = estimator.estimate(meas, cal, s)
    for label, se, sm in (("-n1 (eq. 3-9)", True, False), ("(k1+k2)/2 (eq. 3-16)", False, True)):
        m = thesis.thesis_mass(est, s.correction, s.km_sys, s.ratio, sign_error=se,
                               signed_mean=sm)
        print(f"thesis {label}: m = {m:.4g} kg = {m / ref.mass:.4g} x the true mass")


if __name__ == "__main__":
    main()
