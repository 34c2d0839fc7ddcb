/* The emulator's C API: the firmware core on the sim board (plant + virtual UART), loaded by
 * pmsm_hil.emulator.fwlib with ctypes. All time is device time: a call to emu_run advances the
 * control ISR by whole periods while the firmware is active, and drains the UART at its bit rate. */
#ifndef EMU_H
#define EMU_H

#include <stddef.h>
#include <stdint.h>

typedef struct emu emu_t;

size_t emu_size(void);
void emu_init(emu_t *e);                                  /* defaults: paper A motor, ideal sensors */
int emu_set(emu_t *e, const char *key, double value);      /* 0, or -1 for an unknown key */
int emu_get(const emu_t *e, const char *key, double *value);
void emu_reset(emu_t *e);                                  /* applies the settings: firmware and plant anew */
void emu_rx(emu_t *e, const uint8_t *data, uint32_t n);     /* octets from the host */
/* Runs at most max_ticks control periods (none while the firmware is idle) and writes the octets
 * the UART sent meanwhile into out (at most cap); returns the periods run, *n_out the octets. */
uint32_t emu_run(emu_t *e, uint32_t max_ticks, uint8_t *out, uint32_t cap, uint32_t *n_out);
uint32_t emu_isr_count(const emu_t *e);
uint32_t emu_heartbeat_isr(const emu_t *e);
int emu_state(const emu_t *e);
int emu_active(const emu_t *e);

#endif
