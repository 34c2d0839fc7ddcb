"""python -m pmsm_hil.emulator: the same as `pmsm-hil emulate`."""
import sys

from pmsm_hil.cli.main import main

sys.exit(main(["emulate", *sys.argv[1:]]))
