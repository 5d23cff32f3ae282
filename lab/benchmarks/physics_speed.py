"""Device simulation speed: QUBE env steps per second through the Gymnasium API, and raw batched physics.

Run: ``.venv/bin/python lab/benchmarks/physics_speed.py`` (add ``--quick`` for a smoke run). Numba compiles on
first use (cached on disk afterwards); the warm-up below keeps compilation out of the timings.
"""

import argparse
import time

import gymnasium
import numba
import numpy as np

import fleetrl  # noqa: F401  (registers the envs)
from fleetrl.devices.qube.dynamics import physics_batch, pipeline_settings
from fleetrl.devices.qube.params import qube_unit_params
from fleetrl.envs.registration import QUBE_BALANCE_ID


def env_steps_per_second(n_steps: int, seed: int = 0) -> dict[str, float]:
    """Random actions through ``gymnasium.make`` (TimeLimit and checker wrappers included), one unit."""
    env = gymnasium.make(QUBE_BALANCE_ID, unit=0, fleet_seed=0)
    actions = np.random.default_rng(seed).integers(0, 3, size=n_steps).tolist()
    env.reset(seed=seed)
    for a in actions[:1000]:  # warm-up
        if any(env.step(a)[2:4]):
            env.reset()
    env.reset(seed=seed)
    step = env.step
    reset_time, resets = 0.0, 0
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = step(a)
        if terminated or truncated:
            t0 = time.perf_counter()
            env.reset()
            reset_time += time.perf_counter() - t0
            resets += 1
    total = time.perf_counter() - start
    return {
        "steps_per_s": n_steps / (total - reset_time),
        "steps_per_s_with_resets": n_steps / total,
        "ms_per_reset": 1e3 * reset_time / max(resets, 1),
        "episodes": float(resets),
    }


def batched_physics(n_units: int, n_periods: int, period: float = 0.006) -> dict[str, float]:
    """``n_units`` different units, each advancing ``n_periods`` control periods (RK4 at 1 ms) in one call."""
    settings = pipeline_settings(period, 0.001, quantise=True, velocity_filter=None, delay=True, max_volts=10)
    n_sub, h = int(settings[1]), float(settings[0])
    coefficients = np.stack([qube_unit_params(0, u).coefficients() for u in range(n_units)])
    rng = np.random.default_rng(0)
    states = np.column_stack([np.zeros(n_units), rng.uniform(-0.1, 0.1, n_units), np.zeros((n_units, 2))])
    volts = rng.uniform(-1.44, 1.44, n_units)
    physics_batch(states.copy(), coefficients, volts, 1, n_sub, h)  # warm-up / compile
    start = time.perf_counter()
    physics_batch(states, coefficients, volts, n_periods, n_sub, h)
    elapsed = time.perf_counter() - start
    periods = n_units * n_periods
    return {"periods_per_s": periods / elapsed, "rk4_steps_per_s": periods * n_sub / elapsed}


def main() -> None:
    """Print both figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, for a smoke run")
    args = parser.parse_args()
    n_steps, n_periods = (20_000, 200) if args.quick else (300_000, 4_000)
    env = env_steps_per_second(n_steps)
    print(
        f"QUBE env, one unit, gymnasium.make + random actions ({n_steps} steps): "
        f"{env['steps_per_s']:,.0f} steps/s excluding resets; {env['steps_per_s_with_resets']:,.0f} steps/s "
        f"including {env['episodes']:.0f} device-side resets ({env['ms_per_reset']:.2f} ms each)"
    )
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):  # type: ignore[attr-defined]
        numba.set_num_threads(threads)
        batch = batched_physics(256, n_periods)
        print(
            f"batched physics, 256 units x {n_periods} periods of 6 ms, {threads} thread(s): "
            f"{batch['periods_per_s']:,.0f} unit-periods/s ({batch['rk4_steps_per_s']:,.0f} RK4 steps/s)"
        )


if __name__ == "__main__":
    main()
