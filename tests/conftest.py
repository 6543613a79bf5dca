"""Shared fixtures. Warnings from Drake are errors (see Makefile: DRAKE_DEPRECATION_RUNTIME_SEVERITY)."""

import atexit
import os
import shutil
import tempfile

import pytest

from diagrams.scenario import load_scenario

# Categories a user taught on this machine (scripts/add_category.py) stay out of the tests: none is known
# but those a test teaches into a folder of its own.
os.environ["DUALARM_CATEGORIES"] = tempfile.mkdtemp(prefix="dualarm_categories_")
atexit.register(shutil.rmtree, os.environ["DUALARM_CATEGORIES"], ignore_errors=True)


@pytest.fixture(scope="session")
def scenario():
    return load_scenario()
