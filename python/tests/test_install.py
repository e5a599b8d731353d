"""The module under test is the installed one, not the source tree; with
``CLOTH_WHEEL=1`` (CI's wheel run) it must be the abi3 wheel's."""

import os
import sys

import pytest

import cloth
import cloth._cloth

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "cloth"))


def test_the_module_is_the_installed_one():
    assert os.path.dirname(os.path.abspath(cloth.__file__)) != SOURCE
    assert "site-packages" in cloth._cloth.__file__


@pytest.mark.skipif(os.environ.get("CLOTH_WHEEL") != "1", reason="only in CI's wheel run")
def test_the_wheel_is_built_against_the_stable_abi():
    # abi3 extension modules are named `*.abi3.so` on Linux and macOS.
    assert cloth._cloth.__file__.endswith(".abi3.so"), cloth._cloth.__file__
    assert sys.prefix != sys.base_prefix  # inside the fresh virtual environment
