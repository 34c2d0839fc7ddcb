/* Profile executor: runs the downloaded segments (duration, speed target, ramp, load) on the
 * firmware's own clock. Time comes in as the control period; nothing here reads a clock. */
#ifndef PROFILE_EXEC_H
#define PROFILE_EXEC_H

#include <stdint.h>
#include <stdbool.h>

#include "ramp.h"
#include "proto_gen.h"

#define PROFILE_MAX_SEGMENTS  64u
#define PROFILE_SEGMENT_MAX_S 3600.0f /* one segment; with ts_s >= 10 us its ticks fit a uint32_t */
#define PROFILE_FLAG_CAPTURE  PROTO_SEGMENT_FLAG_CAPTURE
/* the online estimators hold their values in this segment */
#define PROFILE_FLAG_HOLD_EST   PROTO_SEGMENT_FLAG_HOLD_EST
#define PROFILE_KIND_RUN        PROTO_SEGMENT_KIND_RUN
#define PROFILE_KIND_IDENTIFY_R PROTO_SEGMENT_KIND_IDENTIFY_R
#define PROFILE_KIND_COMMISSION PROTO_SEGMENT_KIND_COMMISSION

typedef struct {
    float duration_s;
    float speed_rpm;
    float ramp_rpm_s; /* 0 = step */
    float load_nm;
    uint16_t flags;
    uint16_t kind;   /* PROFILE_KIND_* (protocol enum segment_kind) */
    float inject_a;  /* identify_r: d-axis current; run: i_d excitation amplitude (0: none) */
    float inject_hz; /* run: square-wave excitation frequency */
} profile_segment_t;

typedef struct {
    profile_segment_t seg[PROFILE_MAX_SEGMENTS];
    uint16_t n_declared; /* from profile_clear */
    uint32_t loaded_mask[(PROFILE_MAX_SEGMENTS + 31u) / 32u];
    uint32_t seg_ticks[PROFILE_MAX_SEGMENTS]; /* durations in control periods (set at start) */
    uint16_t index;                           /* running segment */
    uint32_t tick_in_seg;                     /* control periods into the running segment */
    bool begun;
    ramp_t ramp; /* the ramped speed reference */
    bool done;
} profile_exec_t;

typedef struct {
    float speed_ref_rpm;
    float load_nm;
    bool segment_started; /* true in the period a segment begins */
    bool finished;        /* true in the period the last segment ends */
    uint16_t index;
    uint16_t flags;
    uint16_t kind; /* PROFILE_KIND_* of the running segment */
    float inject_a, inject_hz;
    uint32_t tick_in_seg; /* control periods into the running segment */
    uint32_t seg_ticks;   /* length of the running segment in control periods */
} profile_out_t;

void profile_clear(profile_exec_t *p, uint16_t n_segments);
bool profile_set(profile_exec_t *p, uint16_t index, const profile_segment_t *s);
bool profile_complete(const profile_exec_t *p);
void profile_start(profile_exec_t *p, float ts_s);
void profile_step(profile_exec_t *p, float ts_s, profile_out_t *out);

#endif
