/* Host test of board_calc.h (make hostcheck): the numbers docs/board-f28335.md quotes. */
#include <math.h>
#include <stdio.h>

#include "board_calc.h"

static int failures;

#define CHECK(cond)                                                                                \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            printf("FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);                                 \
            failures++;                                                                            \
        }                                                                                          \
    } while (0)

static void baud(uint32_t nominal, uint16_t want_brr, uint32_t want_actual)
{
    const uint16_t brr = calc_sci_brr(BOARD_LSPCLK_HZ, nominal);
    const uint32_t actual = calc_sci_baud(BOARD_LSPCLK_HZ, brr);
    const double err = 100.0 * ((double)actual - (double)nominal) / (double)nominal;
    printf("SCI %7lu baud: BRR %2u -> %7lu baud (%+.2f %%)\n", (unsigned long)nominal,
           (unsigned)brr, (unsigned long)actual, err);
    CHECK(brr == want_brr);
    CHECK(actual == want_actual);
}

static void timing(float ts_s, uint16_t prd, uint16_t code, uint16_t dead, uint16_t lead)
{
    pwm_timing_t t;
    calc_pwm_timing(ts_s, BOARD_DEAD_TIME_NS, BOARD_ADC_LEAD_NS, &t);
    printf("PWM ts %8.2f us: TBPRD %5u CLKDIV code %u dead %3u lead %3u TBCLK, actual %.4f us\n",
           (double)ts_s * 1e6, (unsigned)t.tbprd, (unsigned)t.clkdiv_code, (unsigned)t.dead_tbclk,
           (unsigned)t.lead_tbclk, (double)t.ts_actual_s * 1e6);
    CHECK(t.tbprd == prd);
    CHECK(t.clkdiv_code == code);
    CHECK(t.dead_tbclk == dead);
    CHECK(t.lead_tbclk == lead);
}

int main(void)
{
    const uint16_t load_prd = (uint16_t)(BOARD_SYSCLK_HZ / BOARD_LOAD_PWM_HZ - 1UL);

    baud(921600UL, 4u, 937500UL);
    baud(460800UL, 9u, 468750UL);
    baud(230400UL, 19u, 234375UL);
    baud(115200UL, 40u, 114329UL);

    timing(50.0e-6f, 3750u, 0u, 300u, 150u); /* the 20 kHz default */
    timing(100.0e-6f, 7500u, 0u, 300u, 150u);
    timing(10.0e-6f, 750u, 0u, 300u, 150u);
    timing(1.0e-3f, 37500u, 1u, 150u, 75u); /* 1 ms needs TBCLK / 2 */
    timing(NAN, 3750u, 0u, 300u, 150u);     /* invalid: the default period */

    CHECK(load_prd == 1499u);
    CHECK(calc_dac_cmpa(0.0f, BOARD_LOAD_FULLSCALE_NM, load_prd) == 750u);
    CHECK(calc_dac_cmpa(BOARD_LOAD_FULLSCALE_NM, BOARD_LOAD_FULLSCALE_NM, load_prd) == 1500u);
    CHECK(calc_dac_cmpa(-BOARD_LOAD_FULLSCALE_NM, BOARD_LOAD_FULLSCALE_NM, load_prd) == 0u);
    CHECK(calc_dac_cmpa(100.0f, BOARD_LOAD_FULLSCALE_NM, load_prd) == 1500u);
    CHECK(calc_dac_cmpa(NAN, BOARD_LOAD_FULLSCALE_NM, load_prd) == 750u);
    printf("load PWM-DAC: TBPRD %u, 0 N m -> CMPA %u\n", (unsigned)load_prd,
           (unsigned)calc_dac_cmpa(0.0f, BOARD_LOAD_FULLSCALE_NM, load_prd));

    { /* duty legs at the 20 kHz default: TBPRD 3750, dead band 300 TBCLK */
        uint16_t cmpa = 0u;
        CHECK(calc_leg(0.5f, 3750u, 300u, &cmpa) == CALC_LEG_COMPARE && cmpa == 1875u);
        CHECK(calc_leg(0.25f, 3750u, 300u, &cmpa) == CALC_LEG_COMPARE && cmpa == 2813u);
        CHECK(calc_leg(0.9f, 3750u, 300u, &cmpa) == CALC_LEG_COMPARE && cmpa == 375u);
        CHECK(calc_leg(0.0f, 3750u, 300u, &cmpa) == CALC_LEG_LOW);
        CHECK(calc_leg(0.03f, 3750u, 300u, &cmpa) == CALC_LEG_LOW);     /* 225 TBCLK on < 300 */
        CHECK(calc_leg(0.05f, 3750u, 300u, &cmpa) == CALC_LEG_COMPARE); /* 375 TBCLK on */
        CHECK(calc_leg(0.97f, 3750u, 300u, &cmpa) == CALC_LEG_HIGH);
        CHECK(calc_leg(1.0f, 3750u, 300u, &cmpa) == CALC_LEG_HIGH);
        CHECK(calc_leg(-0.2f, 3750u, 300u, &cmpa) == CALC_LEG_LOW);
        CHECK(calc_leg(NAN, 3750u, 300u, &cmpa) == CALC_LEG_LOW);
    }

    if (failures != 0) {
        printf("%d check(s) failed\n", failures);
        return 1;
    }
    printf("board_calc: all checks passed\n");
    return 0;
}
