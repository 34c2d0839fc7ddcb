/* pmsm-hil firmware on the F28335: start-up order and the background loop.
 * Entry: code_start (flash 0x33FFF6, watchdog off) -> c_int00 (C environment) -> main(). */
#include <string.h>

#include "board.h"

fw_t g_fw; /* the application object: the core's whole state (COFF: .ebss is not zeroed) */

int main(void)
{
    fw_cfg_t cfg;

    /* 1. code and constants that run from RAM: before anything reads a constant */
    sysinit_copy_ramfuncs();
    /* 2. 150 MHz, peripheral clocks; then flash wait states (a RAM function) */
    sysinit_clocks();
    sysinit_flash();
    diag_init();
    /* 3. interrupts off, PIE vectors to the safe default */
    sysinit_pie();

    /* 4. the core */
    memset(&cfg, 0, sizeof(cfg));
    cfg.board = PROTO_BOARD_F28335;
    cfg.can_node = BOARD_CAN_NODE;
    fw_init(&g_fw, &cfg);

    /* 5. peripherals: legs tripped off first, then sensors, link, load hook */
    pwm_init(BOARD_TS_DEFAULT_S);
    load_init();
    adc_init();
    qep_init(BOARD_ENC_COUNTS_DEFAULT);
    sci_init();

    /* 6. time bases run (ADC conversions start), current-sensor offsets with the legs off */
    pwm_start();
    (void)adc_calibrate_offsets(); /* failure: every start is refused (ctrl_isr.c) */

    /* 7. control and link interrupts, gate drivers, watchdog */
    sysinit_install_isrs();
    pwm_gate_enable(true);
    sysinit_watchdog_enable();

    /* background: idle; the watchdog is serviced here only, so a stuck or CPU-starving ISR
     * resets the device */
    for (;;) {
        sysinit_watchdog_service();
        g_diag.bg_loops++;
    }
}
