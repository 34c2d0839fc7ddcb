"""The gap self-test's generator: emulator runs with hidden rig effects, recorded at control rate.

The diagnoser (`pmsm_hil.gap`) never imports this package (tests/test_gap_selftest.py checks it)."""
