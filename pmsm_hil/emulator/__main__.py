"""`python -P -m pmsm_hil.emulator`: the emulator process (see entry.py). As for `pmsm-hil`
(pmsm_hil.cli.main.entry), the objects alive at the end are frozen out of the garbage collector's
last passes: the host waits for this process to end."""

import gc
import sys

from pmsm_hil.emulator.entry import main

try:
    code = main()
finally:
    gc.freeze()
sys.exit(code)
