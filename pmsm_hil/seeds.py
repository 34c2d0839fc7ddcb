"""The emulator's noise seeds are whole numbers 0..SEED_MAX: a sweep file's seed and seed axis,
`pmsm-hil bench --seeds`, the pytest plugin's --hil-seed (no imports: the CLI reads it at start)."""

SEED_MAX = 2**31 - 1
