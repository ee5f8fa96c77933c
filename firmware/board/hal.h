/* hal.h: what the board's core needs from the hardware, and nothing more.
 *
 * The core (firmware/board/qb_*.c) calls only these functions; a backend implements them:
 *   - hal_host.c: the host backend. Time, sensors and motors come from and go to fcb_sim's physics through
 *     callbacks (fcb_sim/hosts/cboard.py drives it in lockstep over ctypes); the UART is two byte queues.
 *   - hal_m0.c: the Cortex-M0 backend (nRF51822): the clocks, RTC1 and UART0 for real (the image boots:
 *     make -C firmware board-m0); the sensors, motors and flash are marked TODO where a team's own drivers go.
 * A team that writes its own board keeps this interface and swaps either side (docs/firmware.md).
 *
 * Units are the chips' and the protocol's: raw MPU6050 words (16.4 LSB per deg/s, 16384 LSB per g), the DMP's
 * quaternion (body-to-earth, earth z up, as floats), pressure in Pa, temperature in 0.01 degC, battery in 10 mV,
 * motor commands 0..1000.
 */
#ifndef QB_HAL_H
#define QB_HAL_H

#include <stddef.h>
#include <stdint.h>

/* Microseconds since boot (the host: the simulator's clock; the M0: the RTC). */
uint64_t hal_time_us(void);

/* UART: bytes received since the last call (at most ``cap``), and bytes to send (all or nothing is not
 * required: returns how many were taken). */
size_t hal_uart_read(uint8_t *buf, size_t cap);
size_t hal_uart_write(const uint8_t *data, size_t len);
/* Bytes the UART's receive queue dropped since boot (it was full): the board reports them (event OVERFLOW). */
uint32_t hal_uart_dropped(void);

/* IMU: one read of the raw words (gx gy gz ax ay az, chip frame). */
void hal_imu_read(int16_t out[6]);
/* The DMP's FIFO: 1 and the quaternion (w x y z) when a new one is there, else 0. */
int hal_dmp_read(float q[4]);

/* Barometer: pressure (Pa) and temperature (0.01 degC). */
void hal_baro_read(int32_t *pressure_pa, int32_t *temperature_cdeg);

/* Battery voltage, 10 mV units (the ADC). */
uint16_t hal_battery_read(void);

/* Motor commands 0..1000 (front, right, back, left). */
void hal_motors_set(const uint16_t ae[4]);

/* An impact the accelerometer felt since the last call (m/s * 1000; 0: none). The host reports the physics'
 * crashes; a real board would detect the spike itself. */
int32_t hal_impact_mm_s(void);

/* The flash log's NOR flash (qb_log.c), addresses from 0 within the log's region: programming only clears bits
 * (an AND), erasing sets them (0xFF); each returns 0, or -1 when it cannot. A backend without erase may leave
 * hal_flash_erase out: qb_log.c's weak default refuses (LOG_RESET then answers NOT_IMPLEMENTED). */
int hal_flash_write(uint32_t addr, const uint8_t *data, size_t len);
int hal_flash_read(uint32_t addr, uint8_t *data, size_t len);
int hal_flash_erase(uint32_t addr, size_t len);

#endif /* QB_HAL_H */
