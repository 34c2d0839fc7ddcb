"""`python -P -m pmsm_hil.emulator`: the emulator process (see entry.py)."""

import sys

from pmsm_hil.emulator.entry import main

sys.exit(main())
