"""Fixtures shared by several test folders."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest


@pytest.fixture(scope="module")
def local_client() -> Iterator[Any]:
    """An in-process Dask client (one worker thread; the compiled kernels are loaded in this
    process), its HTTP server on an ephemeral loopback port, not 8787."""
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=False,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
    )
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()
