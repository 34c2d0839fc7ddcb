/* Start-up of the F28335: RAM copy of the time-critical code, PLL to 150 MHz, peripheral clocks,
 * flash wait states, PIE vector table and interrupt enables, watchdog.
 * The watchdog is off from code_start (C2000Ware DSP2833x_CodeStartBranch.asm, WD_DISABLE = 1)
 * until sysinit_watchdog_enable(), called once everything runs. */
#include <string.h>

#include "board.h"

/* Factory ADC calibration routine in TI-reserved OTP (C2000Ware DSP2833x_ADC_cal.asm, section
 * .adc_cal, NOLOAD): the boot ROM calls it too, but not when the debugger bypasses the boot ROM. */
extern void ADC_cal(void);

/* Linker symbols of the ramfuncs output section (F28335.cmd). */
extern uint16_t RamfuncsLoadStart;
extern uint16_t RamfuncsLoadSize;
extern uint16_t RamfuncsRunStart;

void sysinit_copy_ramfuncs(void)
{
    /* code (.TI.ramfunc: the core, the ISRs, fastRTS) and constants (.econst, .switch) */
    memcpy(&RamfuncsRunStart, &RamfuncsLoadStart, (size_t)&RamfuncsLoadSize);
}

static void sysinit_halt(void)
{
    ESTOP0; /* stops here with the debugger attached; a no-op without it */
    for (;;) {
    }
}

void sysinit_clocks(void)
{
    EALLOW;
    SysCtrlRegs.WDCR = 0x0068u; /* WDDIS: watchdog off during start-up */
    EDIS;

    /* limp mode (missing input clock): do not run the inverter on a 1-5 MHz clock */
    if (SysCtrlRegs.PLLSTS.bit.MCLKSTS != 0u) {
        sysinit_halt();
    }
    /* DIVSEL must be /4 (0) while PLLCR changes */
    if (SysCtrlRegs.PLLSTS.bit.DIVSEL != 0u) {
        EALLOW;
        SysCtrlRegs.PLLSTS.bit.DIVSEL = 0u;
        EDIS;
    }
    if (SysCtrlRegs.PLLCR.bit.DIV != BOARD_PLLCR_DIV) {
        EALLOW;
        SysCtrlRegs.PLLSTS.bit.MCLKOFF = 1u; /* missing-clock detect off while the PLL locks */
        SysCtrlRegs.PLLCR.bit.DIV = BOARD_PLLCR_DIV;
        EDIS;
        while (SysCtrlRegs.PLLSTS.bit.PLLLOCKS != 1u) {
        }
        EALLOW;
        SysCtrlRegs.PLLSTS.bit.MCLKOFF = 0u;
        EDIS;
    }

    EALLOW;
    SysCtrlRegs.PLLSTS.bit.DIVSEL = BOARD_PLL_DIVSEL; /* /2: 30 MHz x 10 / 2 = 150 MHz */
    SysCtrlRegs.HISPCP.all = BOARD_HISPCP;            /* HSPCLK 25 MHz (ADC) */
    SysCtrlRegs.LOSPCP.all = BOARD_LOSPCP;            /* LSPCLK 37.5 MHz (SCI) */

    SysCtrlRegs.PCLKCR0.bit.TBCLKSYNC = 0u; /* ePWM time bases held until pwm_start */
    SysCtrlRegs.PCLKCR0.bit.ADCENCLK = 1u;
    SysCtrlRegs.PCLKCR0.bit.SCIAENCLK = 1u;
    ADC_cal(); /* needs the ADC clock */

    SysCtrlRegs.PCLKCR1.bit.EPWM1ENCLK = 1u;
    SysCtrlRegs.PCLKCR1.bit.EPWM2ENCLK = 1u;
    SysCtrlRegs.PCLKCR1.bit.EPWM3ENCLK = 1u;
    SysCtrlRegs.PCLKCR1.bit.EPWM4ENCLK = 1u;
    SysCtrlRegs.PCLKCR1.bit.EQEP1ENCLK = 1u;
    SysCtrlRegs.PCLKCR3.bit.CPUTIMER1ENCLK = 1u;
    SysCtrlRegs.PCLKCR3.bit.GPIOINENCLK = 1u;
    EDIS;
}

/* Flash: 5 paged / 5 random wait states and 8 OTP wait states at 150 MHz (TI's characterised
 * minimum), pipeline on. Must not run from flash itself: it is a RAM function. */
BOARD_RAMFUNC void sysinit_flash(void)
{
    EALLOW;
    FlashRegs.FOPT.bit.ENPIPE = 1u;
    FlashRegs.FBANKWAIT.bit.PAGEWAIT = 5u;
    FlashRegs.FBANKWAIT.bit.RANDWAIT = 5u;
    FlashRegs.FOTPWAIT.bit.OTPWAIT = 8u;
    FlashRegs.FSTDBYWAIT.bit.STDBYWAIT = 0x01FFu;
    FlashRegs.FACTIVEWAIT.bit.ACTIVEWAIT = 0x01FFu;
    EDIS;
    BOARD_PIPELINE_FLUSH(); /* the last write lands before returning to flash */
}

/* Any interrupt without a handler: legs off, gate drivers off, wait for the watchdog reset. */
__interrupt void isr_unexpected(void)
{
    pwm_off();
    pwm_gate_enable(false);
    sysinit_halt();
}

void sysinit_pie(void)
{
    volatile uint16_t *pie_ier_ifr;
    volatile PINT *vect;
    uint16_t i;

    DINT;
    PieCtrlRegs.PIECTRL.bit.ENPIE = 0u;
    pie_ier_ifr = &PieCtrlRegs.PIEIER1.all; /* PIEIER1, PIEIFR1, ... PIEIER12, PIEIFR12 */
    for (i = 0u; i < 24u; i++) {
        pie_ier_ifr[i] = 0u;
    }
    IER = 0x0000u;
    IFR = 0x0000u;

    EALLOW;
    vect = &PieVectTable.PIE1_RESERVED; /* 128 vectors, 0xD00 .. 0xDFF */
    for (i = 0u; i < 128u; i++) {
        vect[i] = &isr_unexpected;
    }
    EDIS;
    PieCtrlRegs.PIECTRL.bit.ENPIE = 1u;
}

void sysinit_install_isrs(void)
{
    EALLOW;
    PieVectTable.ADCINT = &ctrl_isr;
    PieVectTable.SCIRXINTA = &sci_rx_isr;
    PieVectTable.SCITXINTA = &sci_tx_isr;
    EDIS;

    PieCtrlRegs.PIEIFR1.bit.INTx6 = 0u;
    PieCtrlRegs.PIEIER1.bit.INTx6 = 1u; /* ADCINT: the control ISR */
    PieCtrlRegs.PIEIER9.bit.INTx1 = 1u; /* SCIRXINTA */
    PieCtrlRegs.PIEIER9.bit.INTx2 = 1u; /* SCITXINTA */
    PieCtrlRegs.PIEACK.all = (uint16_t)(PIEACK_GROUP1 | PIEACK_GROUP9);
    IER |= (uint16_t)(M_INT1 | M_INT9);
    EINT; /* INTM = 0 */
    ERTM; /* DBGM = 0: real-time debug mode allowed */
}

void sysinit_watchdog_service(void)
{
    EALLOW;
    SysCtrlRegs.WDKEY = 0x0055u;
    SysCtrlRegs.WDKEY = 0x00AAu;
    EDIS;
}

/* Watchdog: WDCLK = OSCCLK / 512 = 58.6 kHz, 8-bit counter -> reset after 4.4 ms without service.
 * Serviced only from the background loop, so an ISR that never returns, or ISRs that eat all the
 * CPU, reset the device (the legs are off during and after reset: GPIOs are inputs, and the gate
 * drivers' inputs are pulled low on the power stage). */
void sysinit_watchdog_enable(void)
{
    sysinit_watchdog_service();
    EALLOW;
    SysCtrlRegs.SCSR = 0x0000u; /* WDENINT = 0: a timeout resets the device */
    SysCtrlRegs.WDCR = 0x0028u; /* WDCHK = 101, WDDIS = 0, WDPS = /1 */
    EDIS;
}
