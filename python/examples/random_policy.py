"""A random policy in the Gymnasium environment, and how fast the environment runs.

    .venv/bin/python python/examples/random_policy.py [--steps 1000] [--geometry cross]

Runs `--steps` environment steps with actions drawn uniformly from the action space (resetting
when an episode ends), then prints the episodes' returns, the speed in steps per second and the
ratio to real time at the control rate (steps/s divided by control_hz). This is the benchmark
behind the README's figure; run it on one core (`taskset -c 0`) to compare with it.
"""

from __future__ import annotations

import argparse
import time

from pegtwin.gym import PegInHoleEnv


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--geometry", default="cross")
    parser.add_argument("--clearance-mm", type=float, default=0.5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    env = PegInHoleEnv(geometry=args.geometry, clearance_mm=args.clearance_mm)
    env.action_space.seed(args.seed)
    env.reset(seed=args.seed)
    returns, episode_return, depths = [], 0.0, []
    started = time.perf_counter()
    for _ in range(args.steps):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        episode_return += reward
        if terminated or truncated:
            returns.append(episode_return)
            depths.append(info["depth_m"] * 1e3)
            episode_return = 0.0
            env.reset()
    wall = time.perf_counter() - started
    rate = args.steps / wall
    print(f"{len(returns)} episodes, returns {[round(r, 1) for r in returns]}")
    print(f"final depths, mm: {[round(d, 1) for d in depths]}")
    print(
        f"{args.steps} steps in {wall:.2f} s: {rate:.0f} steps/s at {env.control_hz:.0f} Hz "
        f"control = {rate / env.control_hz:.1f}x real time "
        f"({rate * 1000 / env.control_hz:.0f} physics steps/s at 1 kHz)"
    )


if __name__ == "__main__":
    main()
