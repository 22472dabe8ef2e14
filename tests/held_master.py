"""``ident-hw`` with its whole process held now and then: every ``HOLD_EVERY`` s (environment, default
4) a thread makes a C call that keeps the GIL for ``HOLD`` s (default 1): no thread of the master
runs meanwhile, as behind a long compilation or a stuck extension. Each hold is printed to stderr
(``held 1.000 s``). Run as ``python held_master.py <ident-hw arguments>``."""

import ctypes
import os
import sys
import threading
import time

from ident_hw.cli import main


def _hold_now_and_then(every: float, hold: float) -> None:
    usleep = ctypes.PyDLL(None).usleep      # PyDLL: the GIL stays held during the call
    while True:
        time.sleep(every)
        started = time.monotonic()
        usleep(int(hold * 1e6))
        print(f"held {time.monotonic() - started:.3f} s", file=sys.stderr, flush=True)


if __name__ == "__main__":
    every = float(os.environ.get("HOLD_EVERY", "4"))
    hold = float(os.environ.get("HOLD", "1"))
    threading.Thread(target=_hold_now_and_then, args=(every, hold), daemon=True).start()
    sys.exit(main(sys.argv[1:], process_exits=True))
