/* Diagnostics: CPU timer 1 free-running at SYSCLKOUT as a cycle counter (control-ISR cycles,
 * start-up delays) and the board's counters (g_diag, read with the debugger; to be exposed over
 * the protocol later). Only the ISRs write the counters; the background loop only reads them. */
#include "board.h"

volatile board_diag_t g_diag;

void diag_init(void)
{
    g_diag.isr_count = 0UL;
    g_diag.isr_cycles_last = 0UL;
    g_diag.isr_cycles_max = 0UL;
    g_diag.isr_overruns = 0UL;
    g_diag.hw_trips = 0UL;
    g_diag.sci_rx_errors = 0UL;
    g_diag.sci_rx_overflows = 0UL;
    g_diag.qep_phase_errors = 0UL;
    g_diag.bg_loops = 0UL;
    g_diag.ts_actual_s = 0.0f;
    g_diag.adc_offset_lsb[0] = 0.0f;
    g_diag.adc_offset_lsb[1] = 0.0f;
    g_diag.adc_offset_lsb[2] = 0.0f;
    g_diag.adc_cal_ok = 0u;
    g_diag.qep_index_seen = 0u;

    /* CPU timer 1: no prescale, full 32-bit period, no interrupt; stops while the debugger halts */
    CpuTimer1Regs.TCR.bit.TSS = 1u;
    CpuTimer1Regs.PRD.all = 0xFFFFFFFFUL;
    CpuTimer1Regs.TPR.all = 0u;
    CpuTimer1Regs.TPRH.all = 0u;
    CpuTimer1Regs.TCR.bit.TIE = 0u;
    CpuTimer1Regs.TCR.bit.FREE = 0u;
    CpuTimer1Regs.TCR.bit.SOFT = 0u;
    CpuTimer1Regs.TCR.bit.TRB = 1u; /* load PRD into the counter */
    CpuTimer1Regs.TCR.bit.TSS = 0u; /* run */
}

BOARD_RAMFUNC uint32_t diag_now(void)
{
    return CpuTimer1Regs.TIM.all;
}

BOARD_RAMFUNC void diag_isr_end(uint32_t t_entry)
{
    const uint32_t cycles = t_entry - CpuTimer1Regs.TIM.all; /* down counter, modulo 2^32 */
    g_diag.isr_count++;
    g_diag.isr_cycles_last = cycles;
    if (cycles > g_diag.isr_cycles_max) {
        g_diag.isr_cycles_max = cycles;
    }
}

void board_delay_us(uint32_t us)
{
    const uint32_t t0 = CpuTimer1Regs.TIM.all;
    const uint32_t n = us * BOARD_SYSCLK_MHZ;
    while ((uint32_t)(t0 - CpuTimer1Regs.TIM.all) < n) {
    }
}
