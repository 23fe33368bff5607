/*
 * core.c — error recording and array growth shared by every layer (see core.h), and the
 * status table of include/anistar.h (the names and messages of anistar_status), which
 * the errors of every layer use.
 */
#include "core.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

/* ---- status ----------------------------------------------------------------------- */

ANISTAR_API const char *anistar_status_string(anistar_status st) {
    switch (st) {
#define AS_STATUS_MSG_(name, value, msg) \
    case ANISTAR_##name:                 \
        return msg;
        ANISTAR_STATUS_TABLE(AS_STATUS_MSG_)
#undef AS_STATUS_MSG_
    default:
        return "unknown status";
    }
}

ANISTAR_API const char *anistar_status_name(anistar_status st) {
    switch (st) {
#define AS_STATUS_NAME_(name, value, msg) \
    case ANISTAR_##name:                  \
        return #name;
        ANISTAR_STATUS_TABLE(AS_STATUS_NAME_)
#undef AS_STATUS_NAME_
    default:
        return "UNKNOWN";
    }
}

anistar_status as_fail(anistar_context *ctx, anistar_status st, const char *fmt, ...) {
    if (!ctx) return st;
    ctx->last_status = st;
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(ctx->last_error, sizeof ctx->last_error, fmt, ap);
    va_end(ap);
    if (n < 0) {
        /* An encoding error in the message: keep the status's own message. */
        snprintf(ctx->last_error, sizeof ctx->last_error, "%s", anistar_status_string(st));
    }
    /* One line: a message never carries a newline (file names may). */
    for (char *c = ctx->last_error; *c; c++)
        if (*c == '\n' || *c == '\r') *c = ' ';
    return st;
}

void as_clear_error(anistar_context *ctx) {
    if (!ctx) return;
    ctx->last_status = ANISTAR_OK;
    ctx->last_error[0] = '\0';
}

int as_grow(anistar_context *ctx, void **p, size_t *cap, size_t need, size_t elem) {
    if (need <= *cap) return 0;
    size_t ncap = *cap ? *cap : 16;
    while (ncap < need) {
        if (ncap > SIZE_MAX / 2) {
            ncap = need;
            break;
        }
        ncap *= 2;
    }
    size_t old_bytes, new_bytes;
    if (as_mul_size(*cap, elem, &old_bytes) || as_mul_size(ncap, elem, &new_bytes)) return -1;
    void *q = as_realloc(ctx, *p, old_bytes, new_bytes);
    if (!q) return -1;
    *p = q;
    *cap = ncap;
    return 0;
}

/* ---- time ------------------------------------------------------------------------- */

double as_now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int as_halt_due(as_halt *h) {
    if (atomic_load_explicit(&h->halted, memory_order_relaxed)) return 1;
    int why = AS_HALT_NONE;
    if (h->stop && atomic_load_explicit(h->stop, memory_order_relaxed)) why = AS_HALT_STOP;
    else if (h->deadline > 0 && as_now_seconds() > h->deadline) why = AS_HALT_TIME;
    if (why == AS_HALT_NONE) return 0;
    int none = AS_HALT_NONE; /* the first reason found stays */
    atomic_compare_exchange_strong(&h->halted, &none, why);
    return 1;
}
