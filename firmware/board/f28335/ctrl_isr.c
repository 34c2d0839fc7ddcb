/* The control ISR: ADCINT at the end of the conversion sequence that ePWM1 started just before
 * the period start. Per period, as firmware/sim/board.c does with the plant:
 *   sample (ADC currents and v_dc, eQEP count) -> fw_isr() -> apply the command (shadow registers:
 *   the legs switch at the next period start) -> load torque hook -> TX kick.
 * Runs in every period, also between runs (the core then only counts periods for the heartbeat
 * and returns the safe command); between runs it also follows config_ctrl (period, encoder). */
#include "board.h"

/* Between runs the board follows what the host configured: the control period and the encoder
 * resolution (the core accepts config_ctrl only while no run is active). */
static void follow_config(void)
{
    const proto_config_ctrl_t *c = fw_ctrl(&g_fw);
    if (c == 0) {
        return;
    }
    if (c->ts_s != pwm_period()) {
        pwm_set_period(c->ts_s);
    }
    if (c->enc_counts != qep_counts()) {
        qep_set_counts(c->enc_counts);
    }
}

BOARD_RAMFUNC __interrupt void ctrl_isr(void)
{
    const uint32_t t_entry = diag_now();
    const bool between_runs = !fw_active(&g_fw);
    fw_meas_t m;
    fw_cmd_t cmd;

    adc_read(&m);
    m.enc_count = qep_read(between_runs);

    /* board faults reach the core as an over-current (it has no board-fault input): a TZ1 trip
     * that just latched, or current sensors whose offsets were implausible at boot */
    if (pwm_hw_tripped() || !adc_cal_ok()) {
        m.i_a_a = BOARD_FAULT_REPORT_A;
        m.i_b_a = BOARD_FAULT_REPORT_A;
        m.i_c_a = BOARD_FAULT_REPORT_A;
    }

    fw_isr(&g_fw, &m, &cmd);

    pwm_apply(&cmd);
    load_set_torque(cmd.load_nm);
    if (!fw_active(&g_fw)) {
        follow_config();
    }
    sci_tx_kick();

    if (adc_conversion_pending()) {
        g_diag.isr_overruns++; /* the next sequence ended before this ISR: deadline at risk */
    }
    diag_isr_end(t_entry);
    PieCtrlRegs.PIEACK.all = PIEACK_GROUP1;
}
