/*
 * core.c — error recording and array growth shared by every layer (see core.h).
 */
#include "core.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

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
