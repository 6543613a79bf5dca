"""Shared fixtures. Warnings from Drake are errors (see Makefile: DRAKE_DEPRECATION_RUNTIME_SEVERITY)."""

import pytest

from diagrams.scenario import load_scenario


@pytest.fixture(scope="session")
def scenario():
    return load_scenario()
