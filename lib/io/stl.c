/*
 * stl.c — STL: reader (ASCII and binary) and writer (binary).
 *
 * Binary or ASCII is decided by size, not by the first word: a file of exactly
 * 84 + 50 n bytes, n the uint32 at byte 80, is binary even when its header starts with
 * "solid" (several CAD exporters write such headers; test/data/lever.stl is one).
 * Otherwise a file starting with "solid" is ASCII, and anything else of at least 84 bytes
 * is binary (trailing bytes after the n triangles are ignored; fewer bytes is a
 * truncated file).
 *
 * STL stores three vertex copies per triangle: the reader welds equal coordinates
 * (exactly) into one vertex (as_weld_soup); triangles that become degenerate are kept
 * and left to the topology check. Normals are ignored. ASCII facets of more than three
 * vertices (a few exporters write them) become fans; "endsolid" is required (it is how a
 * truncated file is recognised), and several solids in one file are read as one mesh.
 */
#include "io/meshio.h"

#include <float.h>
#include <math.h>
#include <string.h>

static anistar_status stl_binary(anistar_context *ctx, const char *name,
                                 const unsigned char *d, size_t size, as_trimesh *out) {
    uint32_t n = as_ld_u32le(d + 80);
    uint64_t need = 84 + 50 * (uint64_t)n;
    if (need > size)
        return as_io_fail(ctx, name, "binary STL truncated: %u triangles need %llu bytes, the "
                          "file has %zu", n, (unsigned long long)need, size);
    if (n == 0) return as_io_fail(ctx, name, "no triangles (binary STL with 0 facets)");
    double *corners = as_alloc_array(ctx, n, 9 * sizeof(double));
    if (!corners)
        return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory for %u triangles", name, n);
    for (uint32_t i = 0; i < n; i++) {
        const unsigned char *rec = d + 84 + 50 * (size_t)i + 12; /* skip the normal */
        for (int k = 0; k < 9; k++) {
            uint32_t u = as_ld_u32le(rec + 4 * k);
            float f;
            memcpy(&f, &u, sizeof f);
            if (!isfinite(f)) {
                as_free(ctx, corners, (size_t)n * 9 * sizeof(double));
                return as_io_fail(ctx, name, "triangle %u: coordinate is not a finite number",
                                  i);
            }
            corners[9 * (size_t)i + k] = f;
        }
    }
    anistar_status st = as_weld_soup(ctx, name, corners, n, out);
    as_free(ctx, corners, (size_t)n * 9 * sizeof(double));
    return st;
}

typedef struct soup {
    double *c; /* 9 per triangle */
    size_t nt, cap;
} soup;

static int soup_add(anistar_context *ctx, soup *s, const double *a, const double *b,
                    const double *c) {
    if (as_grow(ctx, (void **)&s->c, &s->cap, s->nt + 1, 9 * sizeof(double))) return -1;
    double *p = s->c + 9 * s->nt++;
    memcpy(p, a, 3 * sizeof(double));
    memcpy(p + 3, b, 3 * sizeof(double));
    memcpy(p + 6, c, 3 * sizeof(double));
    return 0;
}

/* Expect the keyword word as the next token (crossing lines). */
static anistar_status expect(as_text *t, const char *word) {
    if (!as_text_skip_ws(t))
        return as_text_fail(t, "unexpected end of file: expected '%s'", word);
    const char *tok;
    size_t len = as_text_token(t, &tok);
    if (!as_token_is(tok, len, word)) {
        char show[32];
        return as_text_fail(t, "expected '%s', found '%s'", word, as_token_show(tok, len, show));
    }
    return ANISTAR_OK;
}

/*
 * design: solid -> (facet [normal ...] outer loop (vertex x y z){3,} endloop endfacet)*
 *   -> endsolid [name] -> (another solid | end of file); corners collected in a growing
 *   array, then welded.
 */
static anistar_status stl_ascii(anistar_context *ctx, const char *name, const char *data,
                                size_t size, as_trimesh *out) {
    as_text t;
    as_text_init(&t, ctx, name, data, size, 0);
    soup s = {NULL, 0, 0};
    char show[32];
    anistar_status st = ANISTAR_OK;
    const char *tok;
    size_t len;
    for (;;) { /* one solid */
        if ((st = expect(&t, "solid"))) goto done;
        as_text_skip_line(&t); /* the name */
        for (;;) {
            if (!as_text_skip_ws(&t)) {
                st = as_text_fail(&t, "unexpected end of file: expected 'facet' or 'endsolid'");
                goto done;
            }
            len = as_text_token(&t, &tok);
            if (as_token_is(tok, len, "endsolid")) {
                as_text_skip_line(&t);
                break;
            }
            if (!as_token_is(tok, len, "facet")) {
                st = as_text_fail(&t, "expected 'facet' or 'endsolid', found '%s'",
                                  as_token_show(tok, len, show));
                goto done;
            }
            /* "normal nx ny nz" (not checked: some exporters write nan), up to "outer". */
            for (int n = 0;; n++) {
                if (!as_text_skip_ws(&t)) {
                    st = as_text_fail(&t, "unexpected end of file: expected 'outer loop'");
                    goto done;
                }
                len = as_text_token(&t, &tok);
                if (as_token_is(tok, len, "outer")) break;
                if (n == 4) {
                    st = as_text_fail(&t, "expected 'outer loop', found '%s'",
                                      as_token_show(tok, len, show));
                    goto done;
                }
            }
            if ((st = expect(&t, "loop"))) goto done;
            double v[3][3];
            int k = 0;
            for (;; k++) {
                if (!as_text_skip_ws(&t)) {
                    st = as_text_fail(&t, "unexpected end of file inside a facet");
                    goto done;
                }
                len = as_text_token(&t, &tok);
                if (as_token_is(tok, len, "endloop")) break;
                if (!as_token_is(tok, len, "vertex")) {
                    st = as_text_fail(&t, "expected 'vertex' or 'endloop', found '%s'",
                                      as_token_show(tok, len, show));
                    goto done;
                }
                double *p = v[k < 2 ? k : 2];
                for (int j = 0; j < 3 && !st; j++) st = as_text_double(&t, 0, "a vertex coordinate", p + j);
                if (st) goto done;
                if (k >= 2) {
                    if (soup_add(ctx, &s, v[0], v[1], v[2])) {
                        st = as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", name);
                        goto done;
                    }
                    memcpy(v[1], v[2], sizeof v[1]); /* fan: v0, previous, next */
                }
            }
            if (k < 3) {
                st = as_text_fail(&t, "facet with %d vertices", k);
                goto done;
            }
            if ((st = expect(&t, "endfacet"))) goto done;
        }
        if (!as_text_skip_ws(&t)) break;
    }
    if (s.nt == 0) {
        st = as_io_fail(ctx, name, "no triangles");
        goto done;
    }
    st = as_weld_soup(ctx, name, s.c, s.nt, out);
done:
    as_free(ctx, s.c, s.cap * 9 * sizeof(double));
    return st;
}

anistar_status as_stl_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    const unsigned char *d = (const unsigned char *)data;
    if (size >= 84 && 84 + 50 * (uint64_t)as_ld_u32le(d + 80) == size)
        return stl_binary(ctx, name, d, size, out);
    size_t i = 0;
    while (i < size && (data[i] == ' ' || data[i] == '\t' || data[i] == '\r' || data[i] == '\n'))
        i++;
    if (size - i >= 5 && as_token_is(data + i, 5, "solid"))
        return stl_ascii(ctx, name, data, size, out);
    if (size >= 84) return stl_binary(ctx, name, d, size, out);
    return as_io_fail(ctx, name, "not an STL file (%zu bytes: too short for binary STL, and "
                      "it does not start with 'solid')", size);
}

static void put_f32(unsigned char *p, double x) {
    float f = (float)x;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    as_st_le(p, u, 4);
}

anistar_status as_stl_write(anistar_context *ctx, const char *path, const as_trimesh *m) {
    if (m->nt > UINT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: too many triangles for STL (%zu)", path, m->nt);
    for (size_t i = 0; i < 3 * m->nv; i++)
        if (fabs(m->xyz[i]) > FLT_MAX)
            return as_fail(ctx, ANISTAR_EINVAL, "%s: vertex %zu: coordinate %g does not fit "
                           "the float32 of STL", path, i / 3, m->xyz[i]);
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    unsigned char head[84];
    memset(head, 0, sizeof head);
    /* Not "solid...": readers that sniff the first word would take it for ASCII. */
    static const char text[] = "binary STL written by anistar";
    memcpy(head, text, sizeof text - 1);
    as_st_le(head + 80, (uint32_t)m->nt, 4);
    as_wfile_write(&w, head, sizeof head);
    unsigned char rec[50];
    for (size_t t = 0; t < m->nt; t++) {
        const double *p[3];
        for (int k = 0; k < 3; k++) p[k] = m->xyz + 3 * (size_t)m->tri[3 * t + k];
        double u[3], v[3], nrm[3];
        for (int k = 0; k < 3; k++) {
            u[k] = p[1][k] - p[0][k];
            v[k] = p[2][k] - p[0][k];
        }
        nrm[0] = u[1] * v[2] - u[2] * v[1];
        nrm[1] = u[2] * v[0] - u[0] * v[2];
        nrm[2] = u[0] * v[1] - u[1] * v[0];
        double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        for (int k = 0; k < 3; k++) put_f32(rec + 4 * k, len > 0 && isfinite(len) ? nrm[k] / len : 0);
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) put_f32(rec + 12 + 12 * j + 4 * k, p[j][k]);
        rec[48] = rec[49] = 0;
        as_wfile_write(&w, rec, sizeof rec);
    }
    return as_wfile_close(&w);
}
