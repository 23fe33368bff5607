/*
 * obj.c — Wavefront OBJ: reader (v and f statements) and writer.
 *
 * Reader notes:
 *  - v x y z [w] [r g b]: only x y z are used;
 *  - f (or the old fo) with 1-based indices, negative indices relative to the vertices
 *    read so far (-1 is the last), each as v, v/vt, v//vn or v/vt/vn; polygons become
 *    fans; faces of fewer than 3 vertices are skipped;
 *  - a backslash before the newline continues a statement on the next line;
 *  - every other statement (vt vn vp g o s usemtl mtllib l p cstype curv surf ...) is
 *    ignored; a line that does not start with a statement name (letters, digits, '_')
 *    is an error, which catches binary files early;
 *  - positive indices may refer to vertices defined later (checked at the end).
 */
#include "io/meshio.h"

#include <string.h>

static int is_ident_char(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '_';
}

/* Parse one face corner "v[/[vt][/[vn]]]" of length len into a 0-based vertex index. */
static anistar_status obj_corner(as_text *t, const char *tok, size_t len, size_t nv_so_far,
                                 int64_t face, int64_t *idx) {
    char show[32];
    int64_t v;
    int ovf;
    size_t n = as_parse_int(tok, &v, &ovf);
    if (n == 0 || n > len)
        return as_text_fail(t, "face %lld: expected a vertex index, found '%s'",
                            (long long)face, as_token_show(tok, len, show));
    /* The rest: nothing, or /[int] or /[int]/[int]. */
    size_t i = n;
    for (int part = 0; i < len && part < 2; part++) {
        if (tok[i] != '/') break;
        i++;
        int64_t dummy;
        int o2;
        size_t k = (i < len) ? as_parse_int(tok + i, &dummy, &o2) : 0;
        if (k > len - i) k = 0;
        i += k;
    }
    if (i != len)
        return as_text_fail(t, "face %lld: malformed vertex reference '%s'", (long long)face,
                            as_token_show(tok, len, show));
    if (ovf || v == 0 || (v < 0 && (uint64_t)(-(v + 1)) >= nv_so_far) ||
        (v > 0 && (uint64_t)v > AS_TRIMESH_MAX_VERTICES))
        return as_text_fail(t, "face %lld: vertex index %s out of range (%zu vertices so far%s)",
                            (long long)face, as_token_show(tok, n, show), nv_so_far,
                            v == 0 ? "; OBJ indices start at 1" : "");
    *idx = v > 0 ? v - 1 : (int64_t)nv_so_far + v;
    return ANISTAR_OK;
}

/*
 * Parse an OBJ file (see the file comment).
 * design: one statement per (continued) line; vertices appended as read; faces fanned
 *   into triangles as read, with relative indices resolved against the vertices so far;
 *   a final pass checks that every index is below the final vertex count.
 */
anistar_status as_obj_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    as_text t;
    as_text_init(&t, ctx, name, data, size, '#');
    t.continuation = 1;
    char show[32];
    anistar_status st = ANISTAR_OK;
    int64_t nface = 0;
    size_t max_line = 0; /* for the message of a forward index that never came */
    int64_t max_index = -1;
    while (as_text_skip_ws(&t)) {
        const char *tok;
        size_t len = as_text_token(&t, &tok);
        int ok = len > 0;
        for (size_t i = 0; i < len; i++) ok &= is_ident_char(tok[i]);
        if (!ok) {
            st = as_text_fail(&t, "expected an OBJ statement, found '%s'",
                              as_token_show(tok, len ? len : 1, show));
            goto fail;
        }
        if (len == 1 && tok[0] == 'v') {
            double x[3];
            for (int k = 0; k < 3 && !st; k++) st = as_text_double(&t, 0, "a vertex coordinate", x + k);
            if (!st) st = as_trimesh_add_vertex(ctx, out, x[0], x[1], x[2]);
            if (st) goto fail;
        } else if ((len == 1 && tok[0] == 'f') || as_token_is(tok, len, "fo")) {
            int64_t k = 0, first = 0, prev = 0;
            for (;; k++) {
                const char *c;
                size_t cl = as_text_token(&t, &c);
                if (cl == 0) break;
                int64_t v = 0;
                st = obj_corner(&t, c, cl, out->nv, nface, &v);
                if (st) goto fail;
                if (v > max_index) {
                    max_index = v;
                    max_line = t.line;
                }
                if (k == 0)
                    first = v;
                else if (k >= 2 && (st = as_trimesh_add_triangle(ctx, out, (int32_t)first,
                                                                (int32_t)prev, (int32_t)v)))
                    goto fail;
                prev = v;
            }
            nface++;
        }
        as_text_skip_line(&t);
    }
    if (max_index >= 0 && (uint64_t)max_index >= out->nv) {
        t.line = max_line;
        st = as_text_fail(&t, "vertex index %lld out of range: the file has %zu vertices",
                          (long long)max_index + 1, out->nv);
        goto fail;
    }
    if (out->nt == 0) {
        st = as_io_fail(ctx, name, "no triangles (%zu vertices, %lld faces)", out->nv,
                        (long long)nface);
        goto fail;
    }
    return ANISTAR_OK;
fail:
    as_trimesh_free(ctx, out);
    return st;
}

anistar_status as_obj_write(anistar_context *ctx, const char *path, const as_trimesh *m) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "# anistar: %zu vertices, %zu triangles\n", m->nv, m->nt);
    for (size_t i = 0; i < m->nv; i++) {
        as_wfile_puts(&w, "v ");
        as_wfile_double(&w, m->xyz[3 * i], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 1], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 2], '\n');
    }
    for (size_t i = 0; i < m->nt; i++)
        as_wfile_printf(&w, "f %ld %ld %ld\n", (long)m->tri[3 * i] + 1,
                        (long)m->tri[3 * i + 1] + 1, (long)m->tri[3 * i + 2] + 1);
    return as_wfile_close(&w);
}
