/* ADC: cascaded sequencer SEQ1, started by ePWM1 SOCA once per control period, simultaneous
 * sampling of two channel pairs:
 *   pair BOARD_ADC_PAIR_IAB: ADCINA = i_a, ADCINB = i_b   -> RESULT0, RESULT1 (same instant)
 *   pair BOARD_ADC_PAIR_ICV: ADCINA = i_c, ADCINB = v_dc  -> RESULT2, RESULT3
 * ADCCLK = HSPCLK / 2 = 12.5 MHz, S/H window (ACQ_PS + 1) ADCCLK. The end of the sequence raises
 * ADCINT (PIE 1.6): the control ISR. Results are read from the zero-wait-state mirror (AdcMirror,
 * right-justified 0..4095) and converted with the calibration of board_cfg.h; the current offsets
 * are measured at boot with the legs off. */
#include "board.h"

typedef struct {
    float off_a, off_b, off_c; /* LSB */
    bool cal_ok;
} adc_state_t;

static adc_state_t s_adc;

void adc_init(void)
{
    /* ADC_cal() has run (sysinit_clocks); power up bandgap, reference and core, then wait */
    AdcRegs.ADCTRL3.all = 0x00E0u;
    board_delay_us(5000UL);

    AdcRegs.ADCTRL1.all = 0u;
    AdcRegs.ADCTRL1.bit.ACQ_PS = BOARD_ADC_ACQ_PS;
    AdcRegs.ADCTRL1.bit.CPS = 0u;
    AdcRegs.ADCTRL1.bit.CONT_RUN = 0u;  /* start-stop: one sequence per SOC */
    AdcRegs.ADCTRL1.bit.SEQ_CASC = 1u;  /* one 16-state sequencer */
    AdcRegs.ADCTRL3.bit.ADCCLKPS = 1u;  /* ADCCLK = 25 MHz / (2 x 1) = 12.5 MHz */
    AdcRegs.ADCTRL3.bit.SMODE_SEL = 1u; /* simultaneous sampling of the A/B pair */
    AdcRegs.ADCMAXCONV.all = 0x0001u;   /* two pair conversions: RESULT0..3 */
    AdcRegs.ADCCHSELSEQ1.bit.CONV00 = BOARD_ADC_PAIR_IAB;
    AdcRegs.ADCCHSELSEQ1.bit.CONV01 = BOARD_ADC_PAIR_ICV;

    AdcRegs.ADCTRL2.all = 0u;
    AdcRegs.ADCTRL2.bit.EPWM_SOCA_SEQ1 = 1u;
    AdcRegs.ADCTRL2.bit.INT_MOD_SEQ1 = 0u; /* interrupt at every end of sequence */
    AdcRegs.ADCTRL2.bit.INT_ENA_SEQ1 = 1u;
    AdcRegs.ADCTRL2.bit.RST_SEQ1 = 1u;
    AdcRegs.ADCST.bit.INT_SEQ1_CLR = 1u;

    s_adc.off_a = BOARD_I_OFFSET_NOMINAL_LSB;
    s_adc.off_b = BOARD_I_OFFSET_NOMINAL_LSB;
    s_adc.off_c = BOARD_I_OFFSET_NOMINAL_LSB;
    s_adc.cal_ok = false;
}

static bool offset_plausible(float off)
{
    const float d = off - BOARD_I_OFFSET_NOMINAL_LSB;
    return d < BOARD_I_OFFSET_TOL_LSB && d > -BOARD_I_OFFSET_TOL_LSB;
}

/* Zero-current offsets: the mean of BOARD_ADC_CAL_SAMPLES conversions with the legs tripped off
 * (and the rotor at rest: a spinning motor with a charged DC link can drive diode currents).
 * Polls the sequencer (interrupts still off). Implausible offsets (sensor missing, not powered)
 * keep the nominal ones and return false: the control ISR then reports a fault to the core in
 * every period, so no run can start. */
bool adc_calibrate_offsets(void)
{
    uint32_t sum_a = 0UL, sum_b = 0UL, sum_c = 0UL;
    uint16_t n = 0u;
    const uint32_t t0 = diag_now();
    const uint32_t timeout = BOARD_ADC_CAL_TIMEOUT_US * BOARD_SYSCLK_MHZ;
    float a, b, c;

    AdcRegs.ADCTRL2.bit.RST_SEQ1 = 1u;
    AdcRegs.ADCST.bit.INT_SEQ1_CLR = 1u;
    while (n < BOARD_ADC_CAL_SAMPLES) {
        if ((uint32_t)(t0 - diag_now()) > timeout) {
            break; /* no conversions: the ePWM time base is not running */
        }
        if (AdcRegs.ADCST.bit.INT_SEQ1 != 0u) {
            sum_a += AdcMirror.ADCRESULT0;
            sum_b += AdcMirror.ADCRESULT1;
            sum_c += AdcMirror.ADCRESULT2;
            AdcRegs.ADCTRL2.bit.RST_SEQ1 = 1u;
            AdcRegs.ADCST.bit.INT_SEQ1_CLR = 1u;
            n++;
        }
    }
    AdcRegs.ADCTRL2.bit.RST_SEQ1 = 1u;
    AdcRegs.ADCST.bit.INT_SEQ1_CLR = 1u;

    s_adc.cal_ok = false;
    if (n == BOARD_ADC_CAL_SAMPLES) {
        a = (float)sum_a / (float)n;
        b = (float)sum_b / (float)n;
        c = (float)sum_c / (float)n;
        if (offset_plausible(a) && offset_plausible(b) && (!BOARD_HAVE_IC || offset_plausible(c))) {
            s_adc.off_a = a;
            s_adc.off_b = b;
            s_adc.off_c = c;
            s_adc.cal_ok = true;
        }
    }
    g_diag.adc_offset_lsb[0] = s_adc.off_a;
    g_diag.adc_offset_lsb[1] = s_adc.off_b;
    g_diag.adc_offset_lsb[2] = s_adc.off_c;
    g_diag.adc_cal_ok = s_adc.cal_ok ? 1u : 0u;
    return s_adc.cal_ok;
}

BOARD_RAMFUNC void adc_read(fw_meas_t *m)
{
    const float ra = (float)AdcMirror.ADCRESULT0;
    const float rb = (float)AdcMirror.ADCRESULT1;
#if BOARD_HAVE_IC
    const float rc = (float)AdcMirror.ADCRESULT2;
#endif
    const float rv = (float)AdcMirror.ADCRESULT3;

    /* re-arm first: the next SOC finds the sequencer at CONV00 even if this ISR runs long */
    AdcRegs.ADCTRL2.bit.RST_SEQ1 = 1u;
    AdcRegs.ADCST.bit.INT_SEQ1_CLR = 1u;

    m->i_a_a = (ra - s_adc.off_a) * BOARD_IA_GAIN_A_PER_LSB;
    m->i_b_a = (rb - s_adc.off_b) * BOARD_IB_GAIN_A_PER_LSB;
#if BOARD_HAVE_IC
    m->i_c_a = (rc - s_adc.off_c) * BOARD_IC_GAIN_A_PER_LSB;
#else
    m->i_c_a = -(m->i_a_a + m->i_b_a);
#endif
    m->v_dc_v = (rv - BOARD_VDC_OFFSET_LSB) * BOARD_VDC_GAIN_V_PER_LSB;
}

BOARD_RAMFUNC bool adc_cal_ok(void)
{
    return s_adc.cal_ok;
}

BOARD_RAMFUNC bool adc_conversion_pending(void)
{
    return AdcRegs.ADCST.bit.INT_SEQ1 != 0u;
}
