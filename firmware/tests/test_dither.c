/* Dither: zero mean over a period, peak-to-peak = gain x step, off when gain is 0. */
#include "check.h"
#include "dither.h"

int main(void)
{
    dither_t d;
    dither_cfg_t c;
    float sum = 0.0f, lo = 1e9f, hi = -1e9f;
    int i;
    c.period = 22u;
    c.gain = 0.6f;
    dither_init(&d, &c);
    for (i = 0; i < 22 * 10; i++) {
        float x = dither_step(&d, 1.5f);
        sum += x;
        if (x < lo) {
            lo = x;
        }
        if (x > hi) {
            hi = x;
        }
    }
    CHECK_NEAR(sum / 220.0f, 0.0f, 1e-5, "zero mean over whole periods");
    CHECK_NEAR(hi - lo, 0.6f * 1.5f, 1e-5, "peak-to-peak is gain x step");
    c.gain = 0.0f;
    dither_init(&d, &c);
    for (i = 0; i < 50; i++) {
        CHECK(dither_step(&d, 1.5f) == 0.0f, "gain 0 disables");
    }
    c.period = 0u;
    c.gain = 1.0f;
    dither_init(&d, &c);
    CHECK(d.cfg.period == 2u, "period clamped to 2");
    return CHECK_DONE();
}
