/* SCI-A (GPIO28 SCIRXDA, GPIO29 SCITXDA): the serial link, 8N1 at BOARD_SCI_BAUD, 16-deep FIFOs.
 *
 * RX: the FIFO interrupt at level 1 (the F2833x SCI has no receive timeout, so a higher level
 * would strand the tail of a frame); the ISR empties the FIFO octet by octet into fw_rx_octet().
 * TX: the FIFO interrupt fires while <= BOARD_SCI_TX_FIFO_LEVEL octets remain; the ISR tops the
 * FIFO up from the core's TX queue and, once the queue is empty, disables itself (a level
 * interrupt would otherwise fire forever). sci_tx_kick() re-enables it after the core queued
 * something (end of the control ISR and of the RX ISR). Nothing here blocks.
 * Octets are uint16_t values 0..255 (16-bit char). */
#include "board.h"
#include "board_calc.h"

void sci_init(void)
{
    const uint16_t brr = calc_sci_brr(BOARD_LSPCLK_HZ, BOARD_SCI_BAUD);

    EALLOW;
    GpioCtrlRegs.GPAPUD.bit.GPIO28 = 0u; /* pull-up: the line idles high */
    GpioCtrlRegs.GPAPUD.bit.GPIO29 = 0u;
    GpioCtrlRegs.GPAQSEL2.bit.GPIO28 = 3u; /* asynchronous: the SCI samples the bits itself */
    GpioCtrlRegs.GPAMUX2.bit.GPIO28 = 1u;  /* SCIRXDA */
    GpioCtrlRegs.GPAMUX2.bit.GPIO29 = 1u;  /* SCITXDA */
    EDIS;

    SciaRegs.SCICTL1.all = 0x0000u; /* held in software reset while configuring */
    SciaRegs.SCICCR.all = 0x0007u;  /* 1 stop bit, no parity, 8 bits, async, idle-line */
    SciaRegs.SCICTL2.all = 0x0000u;
    SciaRegs.SCICTL2.bit.TXINTENA = 1u;
    SciaRegs.SCICTL2.bit.RXBKINTENA = 1u;
    SciaRegs.SCIHBAUD = (uint16_t)((brr >> 8) & 0x00FFu);
    SciaRegs.SCILBAUD = (uint16_t)(brr & 0x00FFu);
    SciaRegs.SCIPRI.bit.FREE = 1u; /* keeps running while the debugger halts */

    SciaRegs.SCIFFTX.all = 0x0000u;
    SciaRegs.SCIFFTX.bit.SCIRST = 1u;
    SciaRegs.SCIFFTX.bit.SCIFFENA = 1u;
    SciaRegs.SCIFFTX.bit.TXFFIL = BOARD_SCI_TX_FIFO_LEVEL;
    SciaRegs.SCIFFTX.bit.TXFFIENA = 0u; /* enabled by sci_tx_kick when there is data */
    SciaRegs.SCIFFTX.bit.TXFFINTCLR = 1u;

    SciaRegs.SCIFFRX.all = 0x0000u;
    SciaRegs.SCIFFRX.bit.RXFFIL = 1u;
    SciaRegs.SCIFFRX.bit.RXFFIENA = 1u;
    SciaRegs.SCIFFRX.bit.RXFFOVRCLR = 1u;
    SciaRegs.SCIFFRX.bit.RXFFINTCLR = 1u;
    SciaRegs.SCIFFCT.all = 0x0000u; /* no delay between transmitted octets */

    SciaRegs.SCICTL1.all = 0x0023u; /* RX and TX enabled, out of software reset */
    SciaRegs.SCIFFTX.bit.TXFIFOXRESET = 1u;
    SciaRegs.SCIFFRX.bit.RXFIFORESET = 1u;
}

BOARD_RAMFUNC void sci_tx_kick(void)
{
    if (fw_tx_level(&g_fw) != 0u) {
        SciaRegs.SCIFFTX.bit.TXFFIENA = 1u;
    }
}

BOARD_RAMFUNC __interrupt void sci_rx_isr(void)
{
    if (SciaRegs.SCIRXST.bit.RXERROR != 0u) {
        /* framing, overrun or break: count, and clear the flags with a software reset (it can
         * also cut the octet being sent; the host drops that frame as it drops a line error).
         * The damaged frame is rejected by the core's COBS/CRC/length checks; the host retries */
        g_diag.sci_rx_errors++;
        SciaRegs.SCICTL1.bit.SWRESET = 0u;
        SciaRegs.SCICTL1.bit.SWRESET = 1u;
    }
    if (SciaRegs.SCIFFRX.bit.RXFFOVF != 0u) {
        g_diag.sci_rx_overflows++;
        SciaRegs.SCIFFRX.bit.RXFFOVRCLR = 1u;
    }
    while (SciaRegs.SCIFFRX.bit.RXFFST != 0u) {
        fw_rx_octet(&g_fw, (uint16_t)(SciaRegs.SCIRXBUF.all & 0x00FFu));
    }
    SciaRegs.SCIFFRX.bit.RXFFINTCLR = 1u;
    PieCtrlRegs.PIEACK.all = PIEACK_GROUP9;
    sci_tx_kick(); /* acks and replies queued by the frames just handled */
}

BOARD_RAMFUNC __interrupt void sci_tx_isr(void)
{
    uint16_t buf[BOARD_SCI_FIFO_DEPTH];
    const uint16_t room = (uint16_t)(BOARD_SCI_FIFO_DEPTH - SciaRegs.SCIFFTX.bit.TXFFST);
    const uint16_t n = fw_tx_pop_n(&g_fw, buf, room);
    uint16_t i;

    for (i = 0u; i < n; i++) {
        SciaRegs.SCITXBUF = buf[i];
    }
    if (n < room) {
        SciaRegs.SCIFFTX.bit.TXFFIENA = 0u; /* queue empty: wait for sci_tx_kick */
    }
    SciaRegs.SCIFFTX.bit.TXFFINTCLR = 1u;
    PieCtrlRegs.PIEACK.all = PIEACK_GROUP9;
}
