/*
 * fracfw on the TMS320F2812: SCI-A and CPU timer 0, written against TI's F281x header files
 * (DSP281x_Device.h: SciaRegs, CpuTimer0Regs, PieCtrlRegs, PieVectTable).
 *
 * NOT COMPILED IN THIS REPOSITORY: it needs TI's C2000 compiler and headers, which the host build
 * and CI do not have. The register and bit-field names follow the DSP281x headers; check them
 * against your header version. What the integrator supplies: fw_hw_apply_voltage() (the command
 * to the current/speed loop, raw channel-0 LSBs) and fw_hw_measure() (speed and current, raw).
 *
 * Clocks: SYSCLKOUT 150 MHz, LSPCLK = SYSCLKOUT / 2 = 75 MHz (LOSPCP = 1) as PROTOCOL.md assumes:
 * SCI baud = LSPCLK / ((BRR + 1) * 8); 115200 -> BRR = 80 (115741 baud, +0.47 %).
 */
#include "DSP281x_Device.h"
#include "fracfw.h"

#define LSPCLK_HZ 75000000ul
#define SYSCLK_HZ 150000000ul
#define BAUD 115200ul
#define MAX_SAMPLE_RATE_HZ 20000ul

extern void fw_hw_apply_voltage(int16_t u_raw);
extern void fw_hw_measure(int16_t *y_raw, int16_t *i_raw);

static fw_t fw; /* all of fracfw's state: no heap */
static uint32_t timer_rate_hz;

static void sci_init(void)
{
    uint16_t brr = (uint16_t)((LSPCLK_HZ + 4ul * BAUD) / (8ul * BAUD) - 1ul); /* 80 */
    SciaRegs.SCICCR.all = 0x0007;  /* 1 stop bit, no parity, 8 data bits, async */
    SciaRegs.SCICTL1.all = 0x0003; /* TX, RX enable; SW reset held */
    SciaRegs.SCIHBAUD = (brr >> 8) & 0xFF;
    SciaRegs.SCILBAUD = brr & 0xFF;
    SciaRegs.SCIFFTX.all = 0xE040; /* FIFO enhancements on, TX FIFO reset released, int clear */
    SciaRegs.SCIFFRX.all = 0x2061; /* RX FIFO, interrupt at 1 word (RXFFIL = 1) */
    SciaRegs.SCIFFCT.all = 0x0000;
    SciaRegs.SCIFFRX.bit.RXFFIENA = 1;
    SciaRegs.SCICTL1.all = 0x0023; /* release SCI from reset */
    SciaRegs.SCIFFTX.bit.TXFIFOXRESET = 1;
    SciaRegs.SCIFFRX.bit.RXFIFORESET = 1;
}

/* CPU timer 0 at the configured sample rate (period in SYSCLKOUT cycles). */
static void timer_set_rate(uint32_t hz)
{
    CpuTimer0Regs.TCR.bit.TSS = 1;
    if (hz == 0ul) {
        return;
    }
    CpuTimer0Regs.PRD.all = SYSCLK_HZ / hz - 1ul;
    CpuTimer0Regs.TPR.all = 0;
    CpuTimer0Regs.TPRH.all = 0;
    CpuTimer0Regs.TCR.bit.TRB = 1; /* reload */
    CpuTimer0Regs.TCR.bit.TIE = 1;
    CpuTimer0Regs.TCR.bit.TSS = 0;
}

/* SCI-A receive FIFO interrupt: every 16 byte times at the latest (1.4 ms at 115200). */
interrupt void fw_sci_rx_isr(void)
{
    while (SciaRegs.SCIFFRX.bit.RXFFST != 0) {
        fw_rx_octet(&fw, SciaRegs.SCIRXBUF.all & 0xFF);
    }
    if (SciaRegs.SCIRXST.bit.RXERROR) { /* overrun/framing: reset the SCI, the frame is lost */
        SciaRegs.SCICTL1.bit.SWRESET = 0;
        SciaRegs.SCICTL1.bit.SWRESET = 1;
    }
    SciaRegs.SCIFFRX.bit.RXFFOVRCLR = 1;
    SciaRegs.SCIFFRX.bit.RXFFINTCLR = 1;
    PieCtrlRegs.PIEACK.all = PIEACK_GROUP9;
}

/* Sample-rate timer interrupt: one sample of the run (or a zero command when idle). */
interrupt void fw_timer0_isr(void)
{
    int16_t u, y, i;
    if (fw_loop_running(&fw)) {
        /* the speed loop: its command comes from the speed at this tick (current unused here) */
        fw_hw_measure(&y, &i);
        fw_sample_measure(&fw, y);
    }
    if (fw_sample_begin(&fw, &u)) {
        fw_hw_apply_voltage(u);
        fw_hw_measure(&y, &i);
        fw_sample_end(&fw, y, i);
    } else {
        fw_hw_apply_voltage(0);
    }
    PieCtrlRegs.PIEACK.all = PIEACK_GROUP1;
}

/* Background loop body: keeps the SCI transmit FIFO full (16 levels) and the timer at the
 * configured rate. fw_tx_octet touches the queues the ISRs fill: run it with interrupts masked. */
void fw_f2812_poll(void)
{
    uint32_t fs;
    DINT;
    while (SciaRegs.SCIFFTX.bit.TXFFST < 16) {
        int32_t v = fw_tx_octet(&fw);
        if (v < 0) {
            break;
        }
        SciaRegs.SCITXBUF = (uint16_t)v & 0xFF;
    }
    fs = fw_sample_rate(&fw);
    EINT;
    if (fs != timer_rate_hz) {
        timer_rate_hz = fs;
        timer_set_rate(fs);
    }
}

/* Call once after InitSysCtrl/InitPieCtrl/InitPieVectTable. boot_id: e.g. a free-running
 * timer's low bits sampled after an external event, or a counter kept in a non-volatile cell. */
void fw_f2812_init(uint16_t boot_id)
{
    fw_init(&fw, boot_id, MAX_SAMPLE_RATE_HZ);
    sci_init();
    EALLOW;
    PieVectTable.RXAINT = &fw_sci_rx_isr;
    PieVectTable.TINT0 = &fw_timer0_isr;
    EDIS;
    PieCtrlRegs.PIEIER9.bit.INTx1 = 1; /* SCIRXINTA */
    PieCtrlRegs.PIEIER1.bit.INTx7 = 1; /* TINT0 */
    IER |= M_INT1 | M_INT9;
    EINT;
}
