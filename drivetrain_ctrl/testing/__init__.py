"""Oracles for tests and benchmarks: the flat reference model of the paper's full drivetrain."""

from __future__ import annotations
