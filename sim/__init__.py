"""Simulation: worlds, tasks, batched rollouts, Ruckig-smoothed execution and the viser viewer."""
