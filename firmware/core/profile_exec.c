#include "profile_exec.h"

void profile_clear(profile_exec_t *p, uint16_t n_segments)
{
    uint16_t i;
    p->n_declared = n_segments;
    for (i = 0u; i < (PROFILE_MAX_SEGMENTS + 31u) / 32u; i++) {
        p->loaded_mask[i] = 0u;
    }
    p->index = 0u;
    p->tick_in_seg = 0u;
    p->begun = false;
    ramp_reset(&p->ramp, 0.0f);
    p->done = false;
}

bool profile_set(profile_exec_t *p, uint16_t index, const profile_segment_t *s)
{
    if (index >= p->n_declared || index >= PROFILE_MAX_SEGMENTS || !(s->duration_s > 0.0f) ||
        !(s->duration_s <= PROFILE_SEGMENT_MAX_S) || !(s->ramp_rpm_s >= 0.0f)) {
        return false;
    }
    p->seg[index] = *s;
    p->loaded_mask[index / 32u] |= (uint32_t)1u << (index % 32u);
    return true;
}

bool profile_complete(const profile_exec_t *p)
{
    uint16_t i;
    if (p->n_declared == 0u) {
        return false;
    }
    for (i = 0u; i < p->n_declared; i++) {
        if ((p->loaded_mask[i / 32u] & ((uint32_t)1u << (i % 32u))) == 0u) {
            return false;
        }
    }
    return true;
}

void profile_start(profile_exec_t *p, float ts_s)
{
    ramp_cfg_t rc;
    uint16_t i;
    for (i = 0u; i < p->n_declared && i < PROFILE_MAX_SEGMENTS; i++) {
        float n = p->seg[i].duration_s / ts_s + 0.5f;
        /* a defined conversion whatever the float: at least 1, at most 2^31 ticks */
        p->seg_ticks[i] = !(n >= 1.0f) ? 1u : (n < 2147483648.0f ? (uint32_t)n : 2147483648u);
    }
    p->index = 0u;
    p->tick_in_seg = 0u;
    p->begun = false;
    rc.rate_rpm_s = 0.0f;
    rc.ts_s = ts_s;
    ramp_init(&p->ramp, &rc);
    p->done = false;
}

/* Output when no segment runs (before the start or after the end): the reference holds, no load. */
static void profile_out_idle(const profile_exec_t *p, profile_out_t *out)
{
    out->speed_ref_rpm = p->ramp.out_rpm;
    out->load_nm = 0.0f;
    out->index = p->index;
    out->flags = 0u;
    out->kind = PROFILE_KIND_RUN;
    out->inject_a = 0.0f;
    out->inject_hz = 0.0f;
    out->tick_in_seg = 0u;
    out->seg_ticks = 0u;
}

void profile_step(profile_exec_t *p, float ts_s, profile_out_t *out)
{
    const profile_segment_t *s;
    out->segment_started = false;
    out->finished = false;
    if (p->done || p->n_declared == 0u) {
        profile_out_idle(p, out);
        return;
    }
    if (!p->begun) {
        p->begun = true;
        p->tick_in_seg = 0u;
        out->segment_started = true;
    } else {
        p->tick_in_seg++;
        if (p->tick_in_seg >= p->seg_ticks[p->index]) {
            if ((uint16_t)(p->index + 1u) >= p->n_declared) {
                p->done = true;
                out->finished = true;
                profile_out_idle(p, out);
                return;
            }
            p->index++;
            p->tick_in_seg = 0u;
            out->segment_started = true;
        }
    }
    s = &p->seg[p->index];
    p->ramp.cfg.ts_s = ts_s;
    ramp_set_rate(&p->ramp, s->ramp_rpm_s);
    out->speed_ref_rpm = ramp_step(&p->ramp, s->speed_rpm);
    out->load_nm = s->load_nm;
    out->index = p->index;
    out->flags = s->flags;
    out->kind = s->kind;
    out->inject_a = s->inject_a;
    out->inject_hz = s->inject_hz;
    out->tick_in_seg = p->tick_in_seg;
    out->seg_ticks = p->seg_ticks[p->index];
}
