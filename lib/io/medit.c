/*
 * medit.c — Medit ASCII .mesh (vertices and triangles) and .sol (per-vertex tensors):
 * readers and writers. MMG and Medit users know these files.
 *
 * .mesh reader notes: free-format tokens with '#' comments; MeshVersionFormatted 1..4
 * and Dimension 3 (2 is rejected); Vertices (x y z ref), Triangles (a b c ref, 1-based),
 * Quadrilaterals (split in two triangles); other sections are skipped: those of known
 * entry size exactly (Edges, Tetrahedra, Corners, Ridges, Required*, Normals...), any
 * other by skipping numbers up to the next keyword; End (optional) stops reading.
 *
 * .sol: SolAtVertices, n, the number of fields and their types (1 scalar, 2 vector,
 * 3 symmetric tensor, 4 full matrix: skipped), n rows of values. Medit stores a symmetric tensor as
 * m11 m12 m22 m13 m23 m33 (lower triangle by rows); we convert to m11 m12 m13 m22 m23 m33.
 */
#include "io/meshio.h"

#include <math.h>
#include <string.h>

/* Sections skipped with a known number of tokens per entry. */
static const struct {
    const char *name;
    int ntok;
} medit_skip[] = {{"Edges", 3},
                  {"Tetrahedra", 5},
                  {"Hexahedra", 9},
                  {"Prisms", 7},
                  {"Pyramids", 6},
                  {"Corners", 1},
                  {"Ridges", 1},
                  {"RequiredVertices", 1},
                  {"RequiredEdges", 1},
                  {"RequiredTriangles", 1},
                  {"RequiredQuadrilaterals", 1},
                  {"RequiredTetrahedra", 1},
                  {"Normals", 3},
                  {"NormalAtVertices", 2},
                  {"NormalAtTriangleVertices", 3},
                  {"Tangents", 3},
                  {"TangentAtVertices", 2}};

static int is_alpha(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

/* The next keyword (a token starting with a letter). 0 at the end of the file. */
static size_t next_token(as_text *t, const char **tok) {
    if (!as_text_skip_ws(t)) return 0;
    return as_text_token(t, tok);
}

/* Skip numbers up to the next keyword (the cursor is left before it). */
static void skip_to_keyword(as_text *t) {
    while (as_text_skip_ws(t) && !is_alpha(*t->p)) {
        const char *tok;
        as_text_token(t, &tok);
    }
}

/* Skip n entries of k tokens each. */
static anistar_status skip_entries(as_text *t, const char *section, int64_t n, int k) {
    for (int64_t i = 0; i < n; i++)
        for (int j = 0; j < k; j++) {
            const char *tok;
            if (!as_text_skip_ws(t))
                return as_text_fail(t, "unexpected end of file in %s (entry %lld of %lld)",
                                    section, (long long)i, (long long)n);
            as_text_token(t, &tok);
        }
    return ANISTAR_OK;
}

/* Read a count for section and check that the rest of the file can hold it with at least
 * min_bytes per entry. */
static anistar_status section_count(as_text *t, const char *section, uint64_t min_bytes,
                                    int64_t *n) {
    anistar_status st = as_text_int(t, 1, "a count", n);
    if (st) return st;
    if (*n < 0) return as_text_fail(t, "%s: negative count %lld", section, (long long)*n);
    if (!as_fits((uint64_t)*n, min_bytes, (uint64_t)(t->end - t->p) + 1))
        return as_text_fail(t, "%s: count %lld exceeds what the rest of the file (%zu bytes) "
                            "can hold", section, (long long)*n, (size_t)(t->end - t->p));
    return ANISTAR_OK;
}

/* MeshVersionFormatted and Dimension: shared by .mesh and .sol. Returns 1 if tok was
 * one of them (and consumed its value), 0 if not, -1 on error (*st set). */
static int header_keyword(as_text *t, const char *tok, size_t len, anistar_status *st) {
    int64_t v;
    if (as_token_is(tok, len, "MeshVersionFormatted")) {
        if ((*st = as_text_int(t, 1, "the version", &v))) return -1;
        if (v < 1 || v > 4) {
            *st = as_text_fail(t, "unsupported MeshVersionFormatted %lld", (long long)v);
            return -1;
        }
        return 1;
    }
    if (as_token_is(tok, len, "Dimension")) {
        if ((*st = as_text_int(t, 1, "the dimension", &v))) return -1;
        if (v != 3) {
            *st = as_text_fail(t, "Dimension %lld is not supported (only 3)", (long long)v);
            return -1;
        }
        return 1;
    }
    return 0;
}

/*
 * design: a keyword loop; Vertices and Triangles allocate after their counts are checked
 *   against the remaining bytes; indices are kept 0-based and checked against the final
 *   vertex count at the end (sections may come in any order).
 */
anistar_status as_medit_parse(anistar_context *ctx, const char *name, const char *data,
                              size_t size, as_trimesh *out) {
    as_text t;
    as_text_init(&t, ctx, name, data, size, '#');
    anistar_status st = ANISTAR_OK;
    char show[32];
    int seen_vertices = 0, seen_version = 0;
    const char *tok;
    size_t len;
    while ((len = next_token(&t, &tok)) > 0) {
        if (!is_alpha(tok[0])) {
            st = as_text_fail(&t, "expected a keyword, found '%s'", as_token_show(tok, len, show));
            goto fail;
        }
        int h = header_keyword(&t, tok, len, &st);
        if (h < 0) goto fail;
        if (h > 0) {
            seen_version |= as_token_is(tok, len, "MeshVersionFormatted");
            continue;
        }
        if (!seen_version) {
            st = as_text_fail(&t, "not a Medit mesh (expected MeshVersionFormatted, found '%s')",
                              as_token_show(tok, len, show));
            goto fail;
        }
        if (as_token_is(tok, len, "End")) break;
        int64_t n;
        if (as_token_is(tok, len, "Vertices")) {
            if (seen_vertices) {
                st = as_text_fail(&t, "a second Vertices section");
                goto fail;
            }
            seen_vertices = 1;
            if ((st = section_count(&t, "Vertices", 8, &n))) goto fail;
            if ((uint64_t)n > AS_TRIMESH_MAX_VERTICES) {
                st = as_text_fail(&t, "too many vertices (%lld)", (long long)n);
                goto fail;
            }
            if ((st = as_trimesh_reserve(ctx, out, (size_t)n, out->nt))) goto fail;
            for (int64_t i = 0; i < n; i++) {
                double x[4];
                for (int k = 0; k < 4 && !st; k++)
                    st = as_text_double(&t, 1, k < 3 ? "a vertex coordinate" : "a reference",
                                        x + k);
                if (st) goto fail;
                double *p = out->xyz + 3 * out->nv++;
                p[0] = x[0], p[1] = x[1], p[2] = x[2];
            }
            continue;
        }
        int quads = as_token_is(tok, len, "Quadrilaterals");
        if (quads || as_token_is(tok, len, "Triangles")) {
            const char *sec = quads ? "Quadrilaterals" : "Triangles";
            int nc = quads ? 4 : 3;
            if ((st = section_count(&t, sec, quads ? 10 : 8, &n))) goto fail;
            if ((st = as_trimesh_reserve(ctx, out, out->cap_v, out->nt + (size_t)n * (nc - 2))))
                goto fail;
            for (int64_t i = 0; i < n; i++) {
                int32_t v[4];
                for (int k = 0; k < nc; k++) {
                    int64_t x;
                    if ((st = as_text_int(&t, 1, "a vertex index", &x))) goto fail;
                    if (x < 1 || (uint64_t)x > AS_TRIMESH_MAX_VERTICES) {
                        st = as_text_fail(&t, "%s %lld: vertex index %lld out of range (indices "
                                          "start at 1)", sec, (long long)i + 1, (long long)x);
                        goto fail;
                    }
                    v[k] = (int32_t)(x - 1);
                }
                int64_t ref;
                if ((st = as_text_int(&t, 1, "a reference", &ref))) goto fail;
                if ((st = as_trimesh_add_triangle(ctx, out, v[0], v[1], v[2]))) goto fail;
                if (quads && (st = as_trimesh_add_triangle(ctx, out, v[0], v[2], v[3]))) goto fail;
            }
            continue;
        }
        int known = 0;
        for (size_t i = 0; i < sizeof medit_skip / sizeof medit_skip[0]; i++)
            if (as_token_is(tok, len, medit_skip[i].name)) {
                if ((st = section_count(&t, medit_skip[i].name, 2 * (uint64_t)medit_skip[i].ntok,
                                        &n)) ||
                    (st = skip_entries(&t, medit_skip[i].name, n, medit_skip[i].ntok)))
                    goto fail;
                known = 1;
                break;
            }
        if (!known) skip_to_keyword(&t);
    }
    if (out->nt == 0 || out->nv == 0) {
        st = as_io_fail(ctx, name, "no triangles (%zu vertices, %zu triangles)", out->nv,
                        out->nt);
        goto fail;
    }
    for (size_t i = 0; i < 3 * out->nt; i++)
        if ((size_t)out->tri[i] >= out->nv) {
            st = as_io_fail(ctx, name, "triangle %zu: vertex index %ld out of range [1, %zu]",
                            i / 3 + 1, (long)out->tri[i] + 1, out->nv);
            goto fail;
        }
    return ANISTAR_OK;
fail:
    as_trimesh_free(ctx, out);
    return st;
}

int as_sol_pick(const int64_t *types, size_t nf, int *width, int *off, int *type) {
    int w = 0, pick = -1;
    *off = 0;
    *type = 0;
    for (size_t f = 0; f < nf; f++) {
        int64_t ty = types[f];
        if (ty < 1 || ty > 4) return -1;
        if ((ty == 3 && *type != 3) || (ty == 1 && *type == 0)) {
            pick = (int)f;
            *off = w;
            *type = (int)ty;
        }
        w += ty == 1 ? 1 : ty == 2 ? 3 : ty == 3 ? 6 : 9;
    }
    *width = w;
    return pick < 0 ? -2 : 0;
}

int as_sol_tensor(int type, const double *s, double o[6]) {
    if (type == 3) {
        o[0] = s[0], o[1] = s[1], o[2] = s[3], o[3] = s[2], o[4] = s[4], o[5] = s[5];
        return 0;
    }
    double h = s[0], e = 1.0 / (h * h);
    if (!(h > 0) || !isfinite(e) || e == 0) return -1;
    o[0] = e, o[1] = 0, o[2] = 0, o[3] = e, o[4] = 0, o[5] = e;
    return 0;
}

/*
 * design: keyword loop as for .mesh; SolAtVertices: count, field count and types, checked
 *   against the remaining bytes (2 bytes per value) before allocation; the first tensor
 *   field (else the first scalar field) is kept, converted to our order or to h^-2 I.
 */
anistar_status as_sol_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, size_t *count, double **tensor) {
    as_text t;
    as_text_init(&t, ctx, name, data, size, '#');
    anistar_status st = ANISTAR_OK;
    char show[32];
    int seen_version = 0;
    double *m = NULL;
    size_t nm = 0;
    *count = 0;
    *tensor = NULL;
    const char *tok;
    size_t len;
    while ((len = next_token(&t, &tok)) > 0) {
        if (!is_alpha(tok[0])) {
            st = as_text_fail(&t, "expected a keyword, found '%s'", as_token_show(tok, len, show));
            goto fail;
        }
        int h = header_keyword(&t, tok, len, &st);
        if (h < 0) goto fail;
        if (h > 0) {
            seen_version |= as_token_is(tok, len, "MeshVersionFormatted");
            continue;
        }
        if (!seen_version) {
            st = as_text_fail(&t, "not a Medit solution (expected MeshVersionFormatted, found "
                              "'%s')", as_token_show(tok, len, show));
            goto fail;
        }
        if (as_token_is(tok, len, "End")) break;
        if (!as_token_is(tok, len, "SolAtVertices")) {
            skip_to_keyword(&t);
            continue;
        }
        if (m) {
            st = as_text_fail(&t, "a second SolAtVertices section");
            goto fail;
        }
        int64_t n, nf;
        if ((st = as_text_int(&t, 1, "the number of vertices", &n)) ||
            (st = as_text_int(&t, 1, "the number of fields", &nf)))
            goto fail;
        if (n < 1 || (uint64_t)n > AS_TRIMESH_MAX_VERTICES || nf < 1 || nf > 64) {
            st = as_text_fail(&t, "SolAtVertices: unsupported counts (%lld vertices, %lld "
                              "fields)", (long long)n, (long long)nf);
            goto fail;
        }
        int64_t types[64];
        for (int64_t f = 0; f < nf; f++)
            if ((st = as_text_int(&t, 1, "a field type", &types[f]))) goto fail;
        int width = 0, pick_off = 0, pick_type = 0;
        int pk = as_sol_pick(types, (size_t)nf, &width, &pick_off, &pick_type);
        if (pk == -1) {
            st = as_text_fail(&t, "unknown solution type (1 scalar, 2 vector, 3 symmetric "
                              "tensor, 4 matrix)");
            goto fail;
        }
        if (pk == -2) {
            st = as_text_fail(&t, "no scalar or tensor field (vectors cannot be metrics)");
            goto fail;
        }
        if (!as_fits((uint64_t)n, 2 * (uint64_t)width, (uint64_t)(t.end - t.p) + 1)) {
            st = as_text_fail(&t, "SolAtVertices: count %lld exceeds what the rest of the file "
                              "(%zu bytes) can hold", (long long)n, (size_t)(t.end - t.p));
            goto fail;
        }
        m = as_alloc_array(ctx, (size_t)n, 6 * sizeof(double));
        if (!m) {
            st = as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory for %lld tensors", name,
                         (long long)n);
            goto fail;
        }
        nm = (size_t)n;
        for (size_t i = 0; i < nm; i++) {
            double s[6] = {0, 0, 0, 0, 0, 0};
            for (int k = 0; k < width; k++) {
                double x;
                if ((st = as_text_double(&t, 1, "a solution value", &x))) goto fail;
                if (k >= pick_off && k < pick_off + (pick_type == 3 ? 6 : 1)) s[k - pick_off] = x;
            }
            if (as_sol_tensor(pick_type, s, m + 6 * i)) {
                st = as_text_fail(&t, "vertex %zu: size %g is not positive (or its metric "
                                  "h^-2 overflows)", i + 1, s[0]);
                goto fail;
            }
        }
    }
    if (!m) {
        st = as_io_fail(ctx, name, "no SolAtVertices section");
        goto fail;
    }
    *count = nm;
    *tensor = m;
    return ANISTAR_OK;
fail:
    as_free(ctx, m, nm * 6 * sizeof(double));
    return st;
}

anistar_status as_medit_write(anistar_context *ctx, const char *path, const as_trimesh *m) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "MeshVersionFormatted 2\nDimension 3\n\nVertices\n%zu\n", m->nv);
    for (size_t i = 0; i < m->nv; i++) {
        as_wfile_double(&w, m->xyz[3 * i], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 1], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 2], ' ');
        as_wfile_puts(&w, "0\n");
    }
    as_wfile_printf(&w, "\nTriangles\n%zu\n", m->nt);
    for (size_t i = 0; i < m->nt; i++)
        as_wfile_printf(&w, "%ld %ld %ld 0\n", (long)m->tri[3 * i] + 1,
                        (long)m->tri[3 * i + 1] + 1, (long)m->tri[3 * i + 2] + 1);
    as_wfile_puts(&w, "\nEnd\n");
    return as_wfile_close(&w);
}

anistar_status as_sol_write(anistar_context *ctx, const char *path, const as_trimesh *m) {
    /* an empty mesh (a run stopped before its first consistent facet) has no tensor
     * array and writes an empty solution */
    if (!m->tensor && m->nv > 0)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: the mesh has no per-vertex tensors to write",
                       path);
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "MeshVersionFormatted 2\nDimension 3\n\nSolAtVertices\n%zu\n1 3\n",
                    m->nv);
    /* Medit order: m11 m12 m22 m13 m23 m33. */
    static const int order[6] = {0, 1, 3, 2, 4, 5};
    for (size_t i = 0; i < m->nv; i++)
        for (int k = 0; k < 6; k++) as_wfile_double(&w, m->tensor[6 * i + order[k]], k < 5 ? ' ' : '\n');
    as_wfile_puts(&w, "\nEnd\n");
    return as_wfile_close(&w);
}
