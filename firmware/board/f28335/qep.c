/* Incremental encoder on eQEP1 (GPIO20 EQEP1A, GPIO21 EQEP1B, GPIO23 EQEP1I).
 *
 * Quadrature count (x4), QPOSMAX = counts - 1 with reset on the maximum (PCRM = 1): QPOSCNT wraps
 * 0..counts-1 in both directions, which is fw_meas_t.enc_count's range. The index pulse latches
 * the count (QPOSILAT, rising edge); that latch becomes count 0 of the reported value, but only
 * between runs (between_runs == true): re-zeroing during a run would be a jump of up to half a
 * turn in the angle the current controller uses. Until the first index has passed while the
 * firmware was idle, count 0 is the power-up position (g_diag.qep_index_seen = 0). */
#include "board.h"

typedef struct {
    uint32_t counts;
    uint32_t index_count; /* QPOSCNT value taken as 0 */
} qep_state_t;

static qep_state_t s_qep;

void qep_init(uint32_t counts)
{
    EALLOW;
    GpioCtrlRegs.GPAPUD.bit.GPIO20 = 0u;
    GpioCtrlRegs.GPAPUD.bit.GPIO21 = 0u;
    GpioCtrlRegs.GPAPUD.bit.GPIO23 = 0u;
    GpioCtrlRegs.GPAQSEL2.bit.GPIO20 = 0u; /* synchronous to SYSCLKOUT */
    GpioCtrlRegs.GPAQSEL2.bit.GPIO21 = 0u;
    GpioCtrlRegs.GPAQSEL2.bit.GPIO23 = 0u;
    GpioCtrlRegs.GPAMUX2.bit.GPIO20 = 1u; /* EQEP1A */
    GpioCtrlRegs.GPAMUX2.bit.GPIO21 = 1u; /* EQEP1B */
    GpioCtrlRegs.GPAMUX2.bit.GPIO23 = 1u; /* EQEP1I */
    EDIS;

    EQep1Regs.QEPCTL.all = 0u; /* counter off while configuring */
    EQep1Regs.QDECCTL.all = 0u;
    EQep1Regs.QDECCTL.bit.QSRC = 0u; /* quadrature count mode */
    EQep1Regs.QDECCTL.bit.SWAP = BOARD_QEP_SWAP;
    EQep1Regs.QCAPCTL.all = 0u; /* capture unit (low-speed timing) unused */
    EQep1Regs.QPOSCTL.all = 0u;
    EQep1Regs.QEINT.all = 0u; /* polled from the control ISR: no interrupts */
    EQep1Regs.QCLR.all = 0x0FFFu;
    EQep1Regs.QPOSINIT = 0UL;
    EQep1Regs.QPOSCNT = 0UL;
    s_qep.index_count = 0UL;
    qep_set_counts(counts);

    EQep1Regs.QEPCTL.bit.FREE_SOFT = 2u; /* keeps counting while the debugger halts */
    EQep1Regs.QEPCTL.bit.PCRM = 1u;      /* reset on the maximum position */
#if BOARD_QEP_USE_INDEX
    EQep1Regs.QEPCTL.bit.IEL = 1u; /* latch QPOSILAT on the index rising edge */
#endif
    EQep1Regs.QEPCTL.bit.QPEN = 1u;
}

void qep_set_counts(uint32_t counts)
{
    if (counts < 4UL) {
        counts = BOARD_ENC_COUNTS_DEFAULT;
    }
    s_qep.counts = counts;
    EQep1Regs.QPOSMAX = counts - 1UL;
    if (EQep1Regs.QPOSCNT >= counts) {
        EQep1Regs.QPOSCNT = EQep1Regs.QPOSCNT % counts;
    }
    /* an index latched with the old resolution means nothing now */
    s_qep.index_count = 0UL;
    g_diag.qep_index_seen = 0u;
    EQep1Regs.QCLR.bit.IEL = 1u;
}

uint32_t qep_counts(void)
{
    return s_qep.counts;
}

BOARD_RAMFUNC uint32_t qep_read(bool between_runs)
{
    uint32_t c = EQep1Regs.QPOSCNT;
    if (EQep1Regs.QFLG.bit.PHE != 0u) { /* A and B changed together: a lost count */
        g_diag.qep_phase_errors++;
        EQep1Regs.QCLR.bit.PHE = 1u;
    }
#if BOARD_QEP_USE_INDEX
    if (between_runs && EQep1Regs.QFLG.bit.IEL != 0u) {
        s_qep.index_count = EQep1Regs.QPOSILAT;
        g_diag.qep_index_seen = 1u;
        EQep1Regs.QCLR.bit.IEL = 1u;
    }
#else
    (void)between_runs;
#endif
    if (c >= s_qep.counts || s_qep.index_count >= s_qep.counts) {
        return 0UL; /* only while QPOSMAX changes; PCRM = 1 keeps QPOSCNT below counts */
    }
    return (c >= s_qep.index_count) ? (c - s_qep.index_count)
                                    : (c + s_qep.counts - s_qep.index_count);
}
