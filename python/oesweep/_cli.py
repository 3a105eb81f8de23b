"""The ``oesweep`` command of the wheel: the command line of the Rust library, run in this
process (``oesweep._oesweep.cli``), so a wheel holds one copy of the engine."""

import signal
import sys

from . import _oesweep


def main() -> int:
    """Run ``oesweep`` with ``sys.argv``; returns its exit code (0, 1 or 2, as the binary)."""
    # The binary's signal dispositions rather than Python's: Ctrl-C outside a sweep ends the
    # process, and during one the engine's handler (which replaces this) stops it resumably,
    # with no KeyboardInterrupt left pending for Python to raise afterwards. SIGPIPE is ignored
    # by both already.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    return _oesweep.cli(sys.argv)


if __name__ == "__main__":
    sys.exit(main())
