"""Energy of a body turning about a sustained contact (found by experiments/fuzz.py,
seeds 32, 58, 62, 112, 222; docs/design.md, "Energy").

The minimal case (tests/test_fuzz.py ``tipping_square``): a 1 m square (1000 kg/m^2)
standing on one corner on a fixed floor, its diagonal 0.3 rad from the vertical,
released from rest; gravity is the only force doing work and the contact does none
(frictionless, or stuck with mu = 0.8), so kinetic + potential must not grow. Prints the
energy gained over 0.3 s per dt and friction, with the observed order, and writes
experiments/results/energy_at_turning_contacts.json.
Usage: python experiments/energy_at_turning_contacts.py
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import jaxdda  # noqa: E402
from tests.test_fuzz import tipping_square  # noqa: E402

DURATION = 0.3


def main() -> None:
    rows = []
    scale = 1000.0 * 9.81 * math.sqrt(2.0)  # m g times the corner's reach
    for friction in (0.0, 0.8):
        for dt in (4e-3, 2e-3, 1e-3):
            traj = jaxdda.simulate(tipping_square(dt, friction), round(DURATION / dt), progress=False)
            total = jaxdda.energy(traj)["total"]
            rows.append({"friction": friction, "dt": dt, "gain_J": float(total.max() - total[0]),
                         "largest_step_gain_J": float(np.diff(total).max()), "scale_J": scale,
                         "converged": bool(np.all(traj.step_converged))})
    print(f"{'mu':>4} {'dt':>7} {'gain (J)':>11} {'per step':>10} {'ratio':>6}")
    for k, r in enumerate(rows):
        prev = rows[k - 1] if k % 3 else None
        ratio = f"{prev['gain_J'] / r['gain_J']:.2f}" if prev and r["gain_J"] > 0 else ""
        print(f"{r['friction']:>4} {r['dt']:>7.0e} {r['gain_J']:>11.3e} {r['largest_step_gain_J']:>10.2e} {ratio:>6}")
    out = Path(__file__).parent / "results" / "energy_at_turning_contacts.json"
    out.write_text(json.dumps({"command": "python experiments/energy_at_turning_contacts.py", "rows": rows}, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
