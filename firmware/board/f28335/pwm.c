/* Inverter legs on ePWM1-3 (leg a, b, c), the ADC trigger, the trip zone and the gate enable.
 *
 * Up-down counting at the control rate (period = 2 TBPRD TBCLK, CTR = 0 is the period start).
 * The core's command (fw_cmd_t) is either forced switch states or three duties:
 *  - states (FCS-MPC: one switching state for a whole period): each leg's A output is an
 *    action-qualifier continuous software force (AQCSFRC: high = upper switch on, low = lower
 *    switch on);
 *  - duties (FOC with SVPWM): the force is released and the compare acts, centre-aligned (set on
 *    CMPA up, clear on CMPA down: on for (TBPRD - CMPA) / TBPRD); a duty whose on- or off-time is
 *    shorter than the dead band becomes the force low or high (calc_leg in board_calc.h).
 * Both AQCSFRC and CMPA are written to their shadow registers in the control ISR and loaded at
 * the next CTR = 0 (AQSFRC.RLDCSF = 0, CMPCTL.LOADAMODE = zero). That is the one-period
 * computation delay the controllers compensate: the output computed from the samples of period
 * k is applied during [k+1, k+2).
 * The dead-band unit makes the complementary B output (active high complementary, both delays
 * BOARD_DEAD_TIME_NS). Off (pwm_on == false) is a one-shot trip-zone force of both outputs low;
 * TZ1 (hardware over-current, active low) trips the same latch.
 * ePWM1 is the master: it syncs ePWM2/3 at CTR = 0 and starts the ADC (SOCA) BOARD_ADC_LEAD_NS
 * before CTR = 0 (compare B on the down count). ePWM4 is the load hook (load.c). */
#include "board.h"
#include "board_calc.h"

#define PWM_CSF_LOW  1u /* AQCSFRC.CSFA: continuous force low  -> lower switch on (after DB) */
#define PWM_CSF_HIGH 2u /* AQCSFRC.CSFA: continuous force high -> upper switch on */

typedef struct {
    pwm_timing_t t;
    float ts_s;   /* requested period */
    bool enabled; /* trip-zone latch cleared by us (legs switching) */
} pwm_state_t;

static pwm_state_t s_pwm;

static volatile struct EPWM_REGS *const k_legs[3] = { &EPwm1Regs, &EPwm2Regs, &EPwm3Regs };

static void pwm_gpio(void)
{
    EALLOW;
    /* EPWM1A..EPWM3B on GPIO0..5; no pull-ups (the gate-driver inputs are pulled down) */
    GpioCtrlRegs.GPAPUD.bit.GPIO0 = 1u;
    GpioCtrlRegs.GPAPUD.bit.GPIO1 = 1u;
    GpioCtrlRegs.GPAPUD.bit.GPIO2 = 1u;
    GpioCtrlRegs.GPAPUD.bit.GPIO3 = 1u;
    GpioCtrlRegs.GPAPUD.bit.GPIO4 = 1u;
    GpioCtrlRegs.GPAPUD.bit.GPIO5 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO0 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO1 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO2 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO3 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO4 = 1u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO5 = 1u;
#if BOARD_USE_TZ1
    /* TZ1 on GPIO12: pull-up, asynchronous input (no qualification delay on a trip) */
    GpioCtrlRegs.GPAPUD.bit.GPIO12 = 0u;
    GpioCtrlRegs.GPAQSEL1.bit.GPIO12 = 3u;
    GpioCtrlRegs.GPAMUX1.bit.GPIO12 = 1u;
#endif
#if BOARD_HAVE_GATE_EN
    /* gate-driver enable on GPIO26, output low (drivers disabled) until pwm_gate_enable(true) */
    GpioDataRegs.GPACLEAR.bit.GPIO26 = 1u;
    GpioCtrlRegs.GPAMUX2.bit.GPIO26 = 0u;
    GpioCtrlRegs.GPADIR.bit.GPIO26 = 1u;
#endif
    EDIS;
}

/* Period-dependent registers of all legs. TBPRD and CMPB are shadowed (loaded at CTR = 0);
 * CLKDIV and the dead band take effect at once, so this runs only while the legs are off. */
static void pwm_write_timing(void)
{
    uint16_t k;
    for (k = 0u; k < 3u; k++) {
        volatile struct EPWM_REGS *p = k_legs[k];
        p->TBPRD = s_pwm.t.tbprd;
        p->TBCTL.bit.CLKDIV = s_pwm.t.clkdiv_code;
        p->DBRED = s_pwm.t.dead_tbclk;
        p->DBFED = s_pwm.t.dead_tbclk;
        p->CMPB = s_pwm.t.lead_tbclk;
    }
    EPwm1Regs.ETSEL.bit.SOCASEL = (s_pwm.t.lead_tbclk == 0u) ? ET_CTR_ZERO : ET_CTRD_CMPB;
    g_diag.ts_actual_s = s_pwm.t.ts_actual_s;
}

void pwm_init(float ts_s)
{
    uint16_t k;

    EALLOW;
    SysCtrlRegs.PCLKCR0.bit.TBCLKSYNC = 0u; /* configure stopped, start together (pwm_start) */
    EDIS;
    pwm_gpio();

    s_pwm.ts_s = ts_s;
    s_pwm.enabled = false;
    calc_pwm_timing(ts_s, BOARD_DEAD_TIME_NS, BOARD_ADC_LEAD_NS, &s_pwm.t);

    for (k = 0u; k < 3u; k++) {
        volatile struct EPWM_REGS *p = k_legs[k];

        /* trip zone first: both outputs forced low before anything else changes */
        EALLOW;
        p->TZSEL.all = 0u;
#if BOARD_USE_TZ1
        p->TZSEL.bit.OSHT1 = 1u;
#endif
        p->TZCTL.bit.TZA = TZ_FORCE_LO;
        p->TZCTL.bit.TZB = TZ_FORCE_LO;
        p->TZEINT.all = 0u;
        p->TZFRC.bit.OST = 1u;
        EDIS;

        /* time base: up-down, shadowed period; ePWM1 master (sync out at zero), 2/3 follow */
        p->TBCTL.all = 0u;
        p->TBCTL.bit.CTRMODE = TB_FREEZE;
        p->TBCTL.bit.PRDLD = TB_SHADOW;
        p->TBCTL.bit.PHSEN = (k == 0u) ? TB_DISABLE : TB_ENABLE;
        p->TBCTL.bit.PHSDIR = TB_UP;
        p->TBCTL.bit.SYNCOSEL = (k == 0u) ? TB_CTR_ZERO : TB_SYNC_IN;
        p->TBCTL.bit.HSPCLKDIV = TB_DIV1;
        p->TBCTL.bit.FREE_SOFT = 0u; /* emulation halt stops the counter (see the doc) */
        p->TBPHS.half.TBPHS = 0u;
        p->TBCTR = 0u;

        /* compare: CMPA for duties, CMPB for the ADC trigger; both shadowed, loaded at CTR = 0 */
        p->CMPCTL.all = 0u;
        p->CMPCTL.bit.SHDWAMODE = CC_SHADOW;
        p->CMPCTL.bit.SHDWBMODE = CC_SHADOW;
        p->CMPCTL.bit.LOADAMODE = CC_CTR_ZERO;
        p->CMPCTL.bit.LOADBMODE = CC_CTR_ZERO;
        p->CMPA.half.CMPA = 0u;

        /* action qualifier: centre-aligned compare on A (duties); a continuous software force
         * (states, and off) overrides it */
        p->AQCTLA.all = 0u;
        p->AQCTLA.bit.CAU = AQ_SET;
        p->AQCTLA.bit.CAD = AQ_CLEAR;
        p->AQCTLB.all = 0u;
        p->AQSFRC.all = 0u; /* RLDCSF = 0: AQCSFRC shadow -> active at CTR = 0 */
        p->AQCSFRC.all = PWM_CSF_LOW;

        /* dead band: A is the source of both outputs, B inverted, rising and falling delays */
        p->DBCTL.all = 0u;
        p->DBCTL.bit.IN_MODE = DBA_ALL;
        p->DBCTL.bit.POLSEL = DB_ACTV_HIC;
        p->DBCTL.bit.OUT_MODE = DB_FULL_ENABLE;

        p->PCCTL.all = 0u; /* chopper off */
        p->ETSEL.all = 0u;
        p->ETPS.all = 0u;
    }
    pwm_write_timing();

    /* ePWM1 starts ADC sequencer 1 once per period */
    EPwm1Regs.ETPS.bit.SOCAPRD = ET_1ST;
    EPwm1Regs.ETSEL.bit.SOCAEN = 1u;

    for (k = 0u; k < 3u; k++) {
        k_legs[k]->TBCTL.bit.CTRMODE = TB_COUNT_UPDOWN;
    }
}

void pwm_start(void)
{
    EALLOW;
    SysCtrlRegs.PCLKCR0.bit.TBCLKSYNC = 1u;
    EDIS;
}

void pwm_set_period(float ts_s)
{
    pwm_off();
    s_pwm.ts_s = ts_s;
    calc_pwm_timing(ts_s, BOARD_DEAD_TIME_NS, BOARD_ADC_LEAD_NS, &s_pwm.t);
    pwm_write_timing();
}

float pwm_period(void)
{
    return s_pwm.ts_s;
}

BOARD_RAMFUNC void pwm_off(void)
{
    EALLOW;
    EPwm1Regs.TZFRC.bit.OST = 1u;
    EPwm2Regs.TZFRC.bit.OST = 1u;
    EPwm3Regs.TZFRC.bit.OST = 1u;
    EDIS;
    /* the state loaded at the next period start is the zero vector 000, which is what the MPCC
     * assumes for the remainder of the period in which the legs are enabled again */
    EPwm1Regs.AQCSFRC.all = PWM_CSF_LOW;
    EPwm2Regs.AQCSFRC.all = PWM_CSF_LOW;
    EPwm3Regs.AQCSFRC.all = PWM_CSF_LOW;
    s_pwm.enabled = false;
}

BOARD_RAMFUNC void pwm_apply(const fw_cmd_t *cmd)
{
    if (!cmd->pwm_on) {
        pwm_off();
        return;
    }
    /* shadow registers: take effect at the next CTR = 0 */
    if (cmd->mode == FW_CMD_DUTIES) {
        const float duty[3] = { cmd->duty_a, cmd->duty_b, cmd->duty_c };
        uint16_t k, cmpa;
        for (k = 0u; k < 3u; k++) {
            const uint16_t force = calc_leg(duty[k], s_pwm.t.tbprd, s_pwm.t.dead_tbclk, &cmpa);
            k_legs[k]->CMPA.half.CMPA = cmpa;
            k_legs[k]->AQCSFRC.all = force;
        }
    } else {
        EPwm1Regs.AQCSFRC.all = (cmd->s_a != 0u) ? PWM_CSF_HIGH : PWM_CSF_LOW;
        EPwm2Regs.AQCSFRC.all = (cmd->s_b != 0u) ? PWM_CSF_HIGH : PWM_CSF_LOW;
        EPwm3Regs.AQCSFRC.all = (cmd->s_c != 0u) ? PWM_CSF_HIGH : PWM_CSF_LOW;
    }
    if (!s_pwm.enabled) {
        /* first period of a run: the active force is still 000 (pwm_off), the chosen state
         * follows at the next period start; a TZ1 that is still asserted latches again at once */
        EALLOW;
        EPwm1Regs.TZCLR.bit.OST = 1u;
        EPwm2Regs.TZCLR.bit.OST = 1u;
        EPwm3Regs.TZCLR.bit.OST = 1u;
        EDIS;
        s_pwm.enabled = true;
    }
}

BOARD_RAMFUNC bool pwm_hw_tripped(void)
{
    /* the one-shot latch set while we had it cleared: only TZ1 can have done that */
    if (s_pwm.enabled && (EPwm1Regs.TZFLG.bit.OST != 0u || EPwm2Regs.TZFLG.bit.OST != 0u ||
                          EPwm3Regs.TZFLG.bit.OST != 0u)) {
        pwm_off();
        g_diag.hw_trips++;
        return true;
    }
    return false;
}

void pwm_gate_enable(bool on)
{
#if BOARD_HAVE_GATE_EN
    if (on) {
        GpioDataRegs.GPASET.bit.GPIO26 = 1u;
    } else {
        GpioDataRegs.GPACLEAR.bit.GPIO26 = 1u;
    }
#else
    (void)on;
#endif
}
