"""Batch work: one picklable :class:`Case` run to one flat record of metrics."""

from __future__ import annotations
