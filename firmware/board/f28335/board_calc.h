/* Pure arithmetic of the board setup (no registers), shared by the board code and its host test
 * (hostcheck/test_calc.c): SCI baud divider, ePWM period/prescaler/dead band, PWM-DAC compare.
 * C28x-safe: 32-bit integer arithmetic written out (int is 16-bit there), float only. */
#ifndef BOARD_CALC_H
#define BOARD_CALC_H

#include <stdint.h>
#include "board_cfg.h"

/* SCI asynchronous baud: baud = LSPCLK / ((BRR + 1) x 8). Nearest BRR. */
static inline uint16_t calc_sci_brr(uint32_t lspclk_hz, uint32_t baud)
{
    const uint32_t div = (lspclk_hz + 4UL * baud) / (8UL * baud);
    return (uint16_t)((div > 1UL) ? (div - 1UL) : 1UL);
}

static inline uint32_t calc_sci_baud(uint32_t lspclk_hz, uint16_t brr)
{
    return lspclk_hz / (8UL * ((uint32_t)brr + 1UL));
}

/* Timing of the up-down counting legs for one control period ts_s:
 *   period = 2 TBPRD TBCLK, TBCLK = SYSCLKOUT / clkdiv, clkdiv the smallest power of two
 *   (TBCTL.CLKDIV code 0..7) that keeps TBPRD within 16 bits. */
typedef struct {
    uint16_t tbprd;       /* TBPRD */
    uint16_t clkdiv_code; /* TBCTL.CLKDIV (HSPCLKDIV stays /1) */
    uint16_t dead_tbclk;  /* DBRED = DBFED (10 bits) */
    uint16_t lead_tbclk;  /* CMPB: the ADC SOC on the down count, this many TBCLK before CTR = 0 */
    float ts_actual_s;    /* the period the hardware really runs */
} pwm_timing_t;

static inline uint16_t calc_ns_to_tbclk(uint32_t ns, uint32_t clkdiv, uint32_t max)
{
    /* ns x SYSCLK_MHz / 1000 / clkdiv, rounded; ns <= 100000 keeps the product in 32 bits */
    const uint32_t den = 1000UL * clkdiv;
    uint32_t n = (ns * BOARD_SYSCLK_MHZ + den / 2UL) / den;
    if (n > max) {
        n = max;
    }
    return (uint16_t)n;
}

/* ts_s outside the core's accepted range (10 us .. 1 ms, or NaN) falls back to the default. */
static inline void calc_pwm_timing(float ts_s, uint32_t dead_ns, uint32_t lead_ns, pwm_timing_t *t)
{
    const float ts_ok = (ts_s >= 1.0e-5f && ts_s <= 1.0e-3f) ? ts_s : BOARD_TS_DEFAULT_S;
    const float half_f = ts_ok * ((float)BOARD_SYSCLK_HZ * 0.5f); /* TBPRD at clkdiv 1 */
    uint32_t clkdiv = 1UL;
    uint16_t code = 0u;
    float prd;
    while (half_f / (float)clkdiv > 65535.0f && code < 7u) {
        clkdiv *= 2UL;
        code++;
    }
    prd = half_f / (float)clkdiv + 0.5f;
    if (prd > 65535.0f) {
        prd = 65535.0f;
    }
    if (prd < 2.0f) {
        prd = 2.0f;
    }
    t->tbprd = (uint16_t)prd;
    t->clkdiv_code = code;
    t->dead_tbclk = calc_ns_to_tbclk(dead_ns, clkdiv, 1023UL);
    t->lead_tbclk = calc_ns_to_tbclk(lead_ns, clkdiv, (uint32_t)t->tbprd / 2UL);
    t->ts_actual_s = 2.0f * (float)t->tbprd * (float)clkdiv / (float)BOARD_SYSCLK_HZ;
}

/* PWM-DAC (up count, set at zero, clear at CMPA): duty = CMPA / (TBPRD + 1);
 * 50 % = 0, 0 % = -full_scale, 100 % = +full_scale, clamped; NaN gives 50 %. */
static inline uint16_t calc_dac_cmpa(float value, float full_scale, uint16_t tbprd)
{
    const float periods = (float)tbprd + 1.0f;
    float duty = 0.5f + value * (0.5f / full_scale);
    if (duty != duty) {
        duty = 0.5f; /* NaN: no torque */
    }
    if (duty < 0.0f) {
        duty = 0.0f;
    }
    if (duty > 1.0f) {
        duty = 1.0f;
    }
    return (uint16_t)(duty * periods + 0.5f);
}

/* Inverter leg with a duty (up-down count, period 2 TBPRD TBCLK; action qualifier: set on CMPA up,
 * clear on CMPA down, so the upper switch is on for (TBPRD - CMPA) / TBPRD of the period, centred
 * on CTR = TBPRD). Returns the continuous software force to load with it: CALC_LEG_COMPARE (none:
 * the compare acts, *cmpa set), or CALC_LEG_LOW / CALC_LEG_HIGH when the on- or off-time would be
 * shorter than one dead band (the dead-band unit would swallow the pulse) or the duty is not a
 * number (low). The codes are AQCSFRC.CSFA's. */
#define CALC_LEG_COMPARE 0u
#define CALC_LEG_LOW     1u
#define CALC_LEG_HIGH    2u

static inline uint16_t calc_leg(float duty, uint16_t tbprd, uint16_t dead_tbclk, uint16_t *cmpa)
{
    const float period = 2.0f * (float)tbprd;
    float on;
    *cmpa = tbprd;
    if (!(duty == duty)) {
        return CALC_LEG_LOW;
    }
    on = duty * period;
    if (on < (float)dead_tbclk) {
        return CALC_LEG_LOW;
    }
    if (period - on < (float)dead_tbclk) {
        return CALC_LEG_HIGH;
    }
    *cmpa = (uint16_t)((1.0f - duty) * (float)tbprd + 0.5f);
    return CALC_LEG_COMPARE;
}

#endif
