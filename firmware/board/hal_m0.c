/* hal_m0.c: the Cortex-M0 backend of hal.h (nRF51822), and the firmware's entry point.
 *
 * It builds and links (make -C firmware board-m0) so that `size` tells what the whole board costs in flash and
 * RAM. The time and the UART are the nRF51's registers (RTC1 at 32768 Hz, UART0 polled); the sensors, motors and
 * flash are where a team's drivers go (marked TODO): the lab's template has them (mpu6050.c, ms5611.c,
 * adc.c, timers.c). qb_m0_main is the reset handler's target: board init, then the loop; between passes the CPU
 * sleeps until an interrupt (a timer tick or a received byte).
 */
#include <stdint.h>
#include <string.h>

#include "hal.h"
#include "qb_board.h"

#define REG(addr) (*(volatile uint32_t *)(addr))
#define RTC1_COUNTER REG(0x40011504u)
#define UART0_EVENTS_RXDRDY REG(0x40002108u)
#define UART0_EVENTS_TXDRDY REG(0x4000211Cu)
#define UART0_RXD REG(0x40002518u)
#define UART0_TXD REG(0x4000251Cu)

void qb_m0_main(void);

static qb_board_t board;
static uint32_t rtc_last, rtc_wraps;

uint64_t hal_time_us(void)
{
    uint32_t now = RTC1_COUNTER & 0xFFFFFFu; /* 24-bit counter */
    uint64_t ticks;
    if (now < rtc_last)
        rtc_wraps++;
    rtc_last = now;
    ticks = ((uint64_t)rtc_wraps << 24) | now;
    return ticks * 15625u / 512u; /* 1e6 / 32768 */
}

size_t hal_uart_read(uint8_t *buf, size_t cap)
{
    size_t n = 0; /* TODO: the receive interrupt's ring buffer; polled here */
    while (n < cap && UART0_EVENTS_RXDRDY) {
        UART0_EVENTS_RXDRDY = 0;
        buf[n++] = (uint8_t)UART0_RXD;
    }
    return n;
}

uint32_t hal_uart_dropped(void)
{
    return 0; /* TODO: the receive ring buffer's overflow count */
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    size_t i; /* TODO: a transmit ring buffer drained by the TXDRDY interrupt; blocking here */
    for (i = 0; i < len; i++) {
        UART0_TXD = data[i];
        while (!UART0_EVENTS_TXDRDY) {
        }
        UART0_EVENTS_TXDRDY = 0;
    }
    return len;
}

void hal_imu_read(int16_t out[6])
{
    memset(out, 0, 6 * sizeof out[0]); /* TODO: the MPU6050's raw words over TWI */
    out[5] = 16384;
}

int hal_dmp_read(float q[4])
{
    q[0] = 1.0f; /* TODO: the DMP's FIFO */
    q[1] = q[2] = q[3] = 0.0f;
    return 0;
}

void hal_baro_read(int32_t *pressure_pa, int32_t *temperature_cdeg)
{
    *pressure_pa = 101325; /* TODO: the MS5611 */
    *temperature_cdeg = 2000;
}

uint16_t hal_battery_read(void)
{
    return 1200; /* TODO: the ADC */
}

void hal_motors_set(const uint16_t ae[4])
{
    (void)ae; /* TODO: the ESCs' pulse widths */
}

int32_t hal_impact_mm_s(void)
{
    return 0; /* TODO: an accelerometer spike past its range */
}

int hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    (void)addr;
    (void)data;
    (void)len;
    return -1; /* the flash log comes later */
}

int hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    (void)addr;
    (void)data;
    (void)len;
    return -1;
}

void qb_m0_main(void)
{
    qb_config_t cfg;
    qb_config_default(&cfg);
    qb_init(&board, &cfg);
    for (;;) {
        qb_poll(&board);
        __asm__ volatile("wfi");
    }
}
