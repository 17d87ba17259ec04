"""Imported once by the forkserver of `gyrodrift fleet`'s own LocalCluster
(`gyrodrift.workflows.fleet.WORKER_PRELOAD`): every worker process forked from it starts with what a
task needs already loaded (dask.distributed, gyrodrift and its scipy, matplotlib with Agg,
the characterization and its outputs) instead of importing them itself, in each worker, inside
its first task."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot
import PIL.PngImagePlugin  # noqa: F401  (savefig's PNG writer)

import gyrodrift.io.imu_data
import gyrodrift.report.html
import gyrodrift.workflows.characterize
import gyrodrift.workflows.fleet  # noqa: F401
