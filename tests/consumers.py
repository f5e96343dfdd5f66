"""Shared by the NIR consumer tests: skip (or fail, in CI) when a consumer toolchain is not installed."""

from __future__ import annotations

import os

import pytest

from cansim.spiking.nir_consumers import consumer_status

STATUS = consumer_status()


def need(consumer: str) -> None:
    """Skip the calling test without ``consumer``; with ``CANSIM_REQUIRE_NIR_CONSUMERS=1`` (``.ci/run``) fail instead."""
    usable, reason = STATUS[consumer]
    if usable:
        return
    msg = f"the optional extra nir-consumers is not installed ({reason})"
    if os.environ.get("CANSIM_REQUIRE_NIR_CONSUMERS") == "1":
        pytest.fail("CANSIM_REQUIRE_NIR_CONSUMERS=1 but " + msg)
    pytest.skip(msg + ": pip install 'cansim[nir-consumers]'")
