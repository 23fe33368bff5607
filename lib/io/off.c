/*
 * off.c — Geomview OFF: reader (ASCII; OFF, COFF, NOFF, CNOFF, STOFF... headers) and
 * writer.
 *
 * Reader notes:
 *  - '#' starts a comment anywhere (before the header too); blank lines are ignored;
 *  - the counts "nv nf [ne]" may follow the header on its line ("OFF 8 6 12"); the edge
 *    count is ignored;
 *  - a vertex is one line: x y z, then anything (normals, colours, texture
 *    coordinates) up to the end of the line is ignored;
 *  - a face is one line: n i1 .. in, then anything (a colour) is ignored; n >= 3 gives a
 *    fan of n - 2 triangles, n < 3 gives none;
 *  - 4OFF, nOFF (other dimensions) and binary OFF are rejected as unsupported.
 */
#include "io/meshio.h"

#include <string.h>

/* Check the header word ([ST][C][N]OFF, in that order); returns 0 if acceptable, or
 * sets *why. */
static int off_header_ok(const char *tok, size_t len, const char **why) {
    *why = NULL;
    if (len < 3 || memcmp(tok + len - 3, "OFF", 3) != 0) return -1;
    size_t i = 0, pre = len - 3;
    if (pre - i >= 2 && tok[i] == 'S' && tok[i + 1] == 'T') i += 2;
    if (i < pre && tok[i] == 'C') i++;
    if (i < pre && tok[i] == 'N') i++;
    if (i < pre && (tok[i] == '4' || tok[i] == 'n')) {
        *why = "4OFF/nOFF (other than 3 dimensions) is not supported";
        return -1;
    }
    return i == pre ? 0 : -1;
}

/*
 * Parse an OFF file (see the file comment).
 * design: header (after comments) -> counts, checked against the bytes left before any
 *   allocation (a vertex line takes at least 6 bytes, a face line 2) -> nv vertex lines
 *   -> nf face lines, each fanned into triangles as it is read.
 */
anistar_status as_off_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    as_text t;
    as_text_init(&t, ctx, name, data, size, '#');
    char show[32];
    if (!as_text_skip_ws(&t)) return as_text_fail(&t, "empty file: expected an OFF header");
    const char *tok;
    size_t len = as_text_token(&t, &tok);
    const char *why;
    if (off_header_ok(tok, len, &why))
        return as_text_fail(&t, "%s (header '%s')", why ? why : "not an OFF file",
                            as_token_show(tok, len, show));
    if (!as_text_at_eol(&t)) {
        /* Counts on the header line, or "OFF BINARY". */
        const char *p = t.p;
        int64_t dummy;
        int ovf;
        if (as_parse_int(p, &dummy, &ovf) == 0) {
            len = as_text_token(&t, &tok);
            if (as_token_is(tok, len, "BINARY"))
                return as_text_fail(&t, "binary OFF is not supported");
            return as_text_fail(&t, "unexpected '%s' after the OFF header",
                                as_token_show(tok, len, show));
        }
    } else if (!as_text_skip_ws(&t)) {
        return as_text_fail(&t, "expected the vertex and face counts, found the end of the "
                            "file");
    }
    int64_t nv, nf;
    anistar_status st = as_text_int(&t, 0, "the vertex count", &nv);
    if (!st) st = as_text_int(&t, 0, "the face count", &nf);
    if (st) return st;
    /* The edge count (optional) and anything else on the line are ignored. */
    as_text_skip_line(&t);
    if (nv < 0 || nf < 0)
        return as_text_fail(&t, "negative count (%lld vertices, %lld faces)", (long long)nv,
                            (long long)nf);
    if ((uint64_t)nv > AS_TRIMESH_MAX_VERTICES)
        return as_text_fail(&t, "too many vertices (%lld)", (long long)nv);
    uint64_t avail = (uint64_t)(t.end - t.p) + 1;
    if (!as_fits((uint64_t)nv, 6, avail) ||
        !as_fits((uint64_t)nf, 2, avail - 6 * (uint64_t)nv))
        return as_text_fail(&t, "the header announces %lld vertices and %lld faces but only "
                            "%zu bytes follow", (long long)nv, (long long)nf,
                            (size_t)(t.end - t.p));
    if (nv == 0 || nf == 0) return as_text_fail(&t, "no triangles (%lld vertices, %lld faces)",
                                                (long long)nv, (long long)nf);
    st = as_trimesh_reserve(ctx, out, (size_t)nv, (size_t)nf);
    if (st) goto fail;

    for (int64_t i = 0; i < nv; i++) {
        if (!as_text_skip_ws(&t)) {
            st = as_text_fail(&t, "unexpected end of file: expected vertex %lld of %lld",
                              (long long)i, (long long)nv);
            goto fail;
        }
        double x[3];
        for (int k = 0; k < 3 && !st; k++) st = as_text_double(&t, 0, "a vertex coordinate", x + k);
        if (st) goto fail;
        out->xyz[3 * i] = x[0];
        out->xyz[3 * i + 1] = x[1];
        out->xyz[3 * i + 2] = x[2];
        out->nv++;
        as_text_skip_line(&t);
    }
    for (int64_t f = 0; f < nf; f++) {
        if (!as_text_skip_ws(&t)) {
            st = as_text_fail(&t, "unexpected end of file: expected face %lld of %lld",
                              (long long)f, (long long)nf);
            goto fail;
        }
        int64_t n;
        st = as_text_int(&t, 0, "the number of vertices of a face", &n);
        if (st) goto fail;
        if (n < 0) {
            st = as_text_fail(&t, "face %lld: negative vertex count %lld", (long long)f,
                              (long long)n);
            goto fail;
        }
        int32_t first = 0, prev = 0;
        for (int64_t k = 0; k < n; k++) {
            int64_t v;
            if (as_text_at_eol(&t)) {
                st = as_text_fail(&t, "face %lld: expected %lld vertex indices, found %lld",
                                  (long long)f, (long long)n, (long long)k);
                goto fail;
            }
            st = as_text_int(&t, 0, "a vertex index", &v);
            if (st) goto fail;
            if (v < 0 || v >= nv) {
                st = as_text_fail(&t, "face %lld: vertex index %lld out of range [0, %lld)",
                                  (long long)f, (long long)v, (long long)nv);
                goto fail;
            }
            if (k == 0)
                first = (int32_t)v;
            else if (k >= 2 && (st = as_trimesh_add_triangle(ctx, out, first, prev, (int32_t)v)))
                goto fail;
            prev = (int32_t)v;
        }
        as_text_skip_line(&t);
    }
    if (out->nt == 0) {
        st = as_text_fail(&t, "no triangles (every face has fewer than 3 vertices)");
        goto fail;
    }
    return ANISTAR_OK;
fail:
    as_trimesh_free(ctx, out);
    return st;
}

anistar_status as_off_write(anistar_context *ctx, const char *path, const as_trimesh *m) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "OFF\n%zu %zu 0\n", m->nv, m->nt);
    for (size_t i = 0; i < m->nv; i++) {
        as_wfile_double(&w, m->xyz[3 * i], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 1], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 2], '\n');
    }
    for (size_t i = 0; i < m->nt; i++)
        as_wfile_printf(&w, "3 %ld %ld %ld\n", (long)m->tri[3 * i], (long)m->tri[3 * i + 1],
                        (long)m->tri[3 * i + 2]);
    return as_wfile_close(&w);
}
