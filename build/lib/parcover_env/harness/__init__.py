"""Running policies at scale: rollouts, bench sweeps, statistics, Minari datasets, the Ray backend."""
