"""The ``oesweep`` command of the wheel: the command line of the Rust library, run in this
process (``oesweep._oesweep.cli``), so a wheel holds one copy of the engine."""

import signal
import sys

from . import _oesweep


def main() -> int:
    """Run ``oesweep`` with ``sys.argv``; returns its exit code (0, 1 or 2, as the binary, 130
    after Ctrl-C). The SIGINT handler is the caller's again when it returns."""
    # The binary's signal dispositions rather than Python's while the command runs: Ctrl-C
    # outside a sweep ends the process, and during one the engine's handler (which replaces
    # this, and puts it back) stops it resumably, with no KeyboardInterrupt left pending for
    # Python to raise afterwards. SIGPIPE is ignored by both already.
    previous = signal.signal(signal.SIGINT, signal.SIG_DFL)
    try:
        return _oesweep.cli(sys.argv)
    finally:
        # None: a handler Python did not install, which it cannot put back; SIG_DFL stays.
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


if __name__ == "__main__":
    sys.exit(main())
