"""Shared by the Python reader's tests: Debian's python3 and python/ on the path, then `rtpack`.

The Debian python3-* packages (numpy, zstandard, crcmod) are installed for /usr/bin/python3, not for a
pyenv or venv python3 that may come first on PATH: without numpy, the test re-runs itself under it.
"""
import os
import sys

try:
    import numpy  # noqa: F401
except ImportError:
    if os.path.exists("/usr/bin/python3") and os.path.realpath(sys.executable) != os.path.realpath("/usr/bin/python3"):
        os.execv("/usr/bin/python3", ["/usr/bin/python3"] + sys.argv)
    raise

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.dont_write_bytecode = True  # no __pycache__ left in python/ or tests/python/
sys.path.insert(0, os.path.join(ROOT, "python"))
import rtpack  # noqa: E402,F401
