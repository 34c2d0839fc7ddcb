/* F28335 board support: the modules that adapt the hardware to the firmware core (fw.h), the
 * same contract as the emulator's firmware/sim/board.c (docs/board-f28335.md).
 *
 * Execution contexts (all interrupts non-nested: the CPU sets INTM on ISR entry and nothing here
 * clears it, so every call into the core is serialised without critical sections):
 *   ctrl_isr      ADCINT (PIE 1.6), once per control period: fw_isr()
 *   sci_rx_isr    SCIRXINTA (PIE 9.1): fw_rx_octet() per received octet
 *   sci_tx_isr    SCITXINTA (PIE 9.2): fw_tx_pop_n() into the TX FIFO
 *   main loop     watchdog, diagnostics; never calls into the core.
 * Do not enable interrupt nesting without moving the RX feed into the control ISR first. */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>
#include <stdbool.h>

#include "DSP2833x_Device.h"
#include "DSP2833x_EPwm_defines.h"
#include "board_cfg.h"
#include "fw.h"

/* Time-critical board functions run from RAM (.TI.ramfunc, copied at start-up; the core objects
 * are compiled with --ramfunc=on, see the Makefile). Host syntax checks see an empty macro. */
#if defined(__TI_COMPILER_VERSION__)
#define BOARD_RAMFUNC          __attribute__((ramfunc))
#define BOARD_PIPELINE_FLUSH() __asm(" RPT #7 || NOP")
#else
#define BOARD_RAMFUNC
#define BOARD_PIPELINE_FLUSH() ((void)0)
#endif

/* The application object (main.c). */
extern fw_t g_fw;

/* ---------------------------------------------------------------- diag.c: CPU timer 1, counters */
typedef struct {
    uint32_t isr_count;        /* control ISRs */
    uint32_t isr_cycles_last;  /* SYSCLKOUT cycles of the last control ISR (entry to exit) */
    uint32_t isr_cycles_max;   /* since reset (write 0 from the debugger to restart) */
    uint32_t isr_overruns;     /* the next conversion finished before the ISR did */
    uint32_t hw_trips;         /* TZ1 one-shot trips seen while the legs were enabled */
    uint32_t sci_rx_errors;    /* framing/overrun/break (SCIRXST.RXERROR) */
    uint32_t sci_rx_overflows; /* RX FIFO overflows */
    uint32_t qep_phase_errors; /* eQEP quadrature phase errors */
    uint32_t bg_loops;         /* background loop passes */
    float ts_actual_s;         /* the control period the ePWMs run */
    float adc_offset_lsb[3];   /* current-sensor offsets in use */
    uint16_t adc_cal_ok;       /* boot offset calibration accepted */
    uint16_t qep_index_seen;   /* count 0 is referenced to the encoder index */
} board_diag_t;

extern volatile board_diag_t g_diag;

void diag_init(void);                  /* starts CPU timer 1 free-running at SYSCLKOUT */
BOARD_RAMFUNC uint32_t diag_now(void); /* down-counting cycle stamp */
BOARD_RAMFUNC void diag_isr_end(uint32_t t_entry);
void board_delay_us(uint32_t us);

/* ---------------------------------------------------------------- sysinit.c */
void sysinit_copy_ramfuncs(void);       /* flash -> RAM copy of ramfuncs (code and constants) */
void sysinit_clocks(void);              /* PLL 150 MHz, prescalers, peripheral clocks, ADC_cal */
BOARD_RAMFUNC void sysinit_flash(void); /* flash wait states and pipeline (runs from RAM) */
void sysinit_pie(void);                 /* PIE on, all vectors to isr_unexpected */
void sysinit_install_isrs(void);        /* control, SCI RX/TX vectors; PIE/CPU enables */
void sysinit_watchdog_enable(void);
void sysinit_watchdog_service(void);
__interrupt void isr_unexpected(void);

/* ---------------------------------------------------------------- pwm.c: ePWM1-3 legs */
void pwm_init(float ts_s);       /* legs tripped off, time bases stopped */
void pwm_start(void);            /* TBCLKSYNC: all time bases start together */
void pwm_set_period(float ts_s); /* only while the legs are off */
float pwm_period(void);          /* the ts_s last configured */
BOARD_RAMFUNC void pwm_apply(const fw_cmd_t *cmd);
BOARD_RAMFUNC void pwm_off(void);
BOARD_RAMFUNC bool pwm_hw_tripped(void); /* TZ1 latched while enabled (once per event) */
void pwm_gate_enable(bool on);

/* ---------------------------------------------------------------- adc.c */
void adc_init(void);
bool adc_calibrate_offsets(void);          /* PWM off, time bases running, interrupts off */
BOARD_RAMFUNC void adc_read(fw_meas_t *m); /* currents, v_dc; re-arms the sequencer */
BOARD_RAMFUNC bool adc_cal_ok(void);
BOARD_RAMFUNC bool adc_conversion_pending(void); /* a newer sequence has completed */

/* ---------------------------------------------------------------- qep.c: eQEP1 */
void qep_init(uint32_t counts);
void qep_set_counts(uint32_t counts); /* only between runs */
uint32_t qep_counts(void);
BOARD_RAMFUNC uint32_t qep_read(bool between_runs);

/* ---------------------------------------------------------------- sci.c: SCI-A */
void sci_init(void);
BOARD_RAMFUNC void sci_tx_kick(void); /* enable the TX FIFO interrupt if octets are queued */
BOARD_RAMFUNC __interrupt void sci_rx_isr(void);
BOARD_RAMFUNC __interrupt void sci_tx_isr(void);

/* ---------------------------------------------------------------- load.c: load-machine hook */
void load_init(void);
BOARD_RAMFUNC void load_set_torque(float load_nm);

/* ---------------------------------------------------------------- ctrl_isr.c */
BOARD_RAMFUNC __interrupt void ctrl_isr(void);

#endif
