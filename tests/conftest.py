"""Shared fixtures. Warnings from Drake are errors (see Makefile: DRAKE_DEPRECATION_RUNTIME_SEVERITY)."""

import os
import tempfile

import pytest

from diagrams.scenario import load_scenario

# Categories a user taught on this machine (scripts/add_category.py) stay out of the tests: none is known
# but those a test teaches into a folder of its own.
os.environ["DUALARM_CATEGORIES"] = tempfile.mkdtemp(prefix="dualarm_categories_")


@pytest.fixture(scope="session")
def scenario():
    return load_scenario()
