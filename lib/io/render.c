/*
 * render.c — the software rasterizer of render.h: projection and fit, flat shading,
 * z-buffered supersampled rasterization in bands, edges, colormap, legend with a
 * built-in bitmap font, and the per-triangle measures.
 */
#include "io/render.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define AS_PI 3.14159265358979323846

enum {
    BAND_SAMPLES = 1 << 18, /* samples per band (depth 8 bytes + id 4 bytes each) */
    GLYPH_W = 5,
    GLYPH_H = 7,   /* cap height: digits and capitals-size letters */
    GLYPH_ROWS = 9 /* with two rows of descenders (g j p q y) */
};

/* Edge drawing: half width (pixels), opacity, and the fade over the shortest projected
 * altitude h of a triangle: alpha = EDGE_ALPHA * clamp((h - FADE_LO) / (FADE_HI - FADE_LO)). */
static const double EDGE_HALF = 0.5, EDGE_ALPHA = 0.8, FADE_LO = 1.5, FADE_HI = 4.0;

/* Colours in [0, 1]. */
static const double PLAIN[3] = {0.80, 0.82, 0.87};   /* no values */
static const double NOVALUE[3] = {0.55, 0.55, 0.55}; /* NaN value */
static const double BRICK[3] = {0.78, 0.30, 0.24};   /* back-face tint */
static const unsigned char TEXT[3] = {30, 30, 30};

/* Viridis (matplotlib's perceptual colormap) at t = 0, 1/8, ..., 1. */
static const unsigned char VIRIDIS[9][3] = {
    {0x44, 0x01, 0x54}, {0x47, 0x2d, 0x7b}, {0x3b, 0x52, 0x8b}, {0x2c, 0x72, 0x8e},
    {0x21, 0x91, 0x8c}, {0x28, 0xae, 0x80}, {0x5e, 0xc9, 0x62}, {0xad, 0xdc, 0x30},
    {0xfd, 0xe7, 0x25}};

void as_render_params_init(as_render_params *p) {
    memset(p, 0, sizeof *p);
    p->width = 1024;
    p->height = 768;
    p->azimuth = 30;
    p->elevation = 20;
    p->up = 2;
    p->supersample = 3;
    p->edges = 1;
    p->legend = 1;
    p->vmin = NAN;
    p->vmax = NAN;
    p->label = NULL;
    p->ambient = 0.35;
    p->diffuse = 0.65;
    p->background[0] = p->background[1] = p->background[2] = 255;
}

void as_render_colormap(double t, double rgb[3]) {
    if (isnan(t)) {
        memcpy(rgb, NOVALUE, sizeof NOVALUE);
        return;
    }
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    double x = t * 8;
    int i = (int)x;
    if (i > 7) i = 7;
    double f = x - i;
    for (int k = 0; k < 3; k++)
        rgb[k] = ((1 - f) * VIRIDIS[i][k] + f * VIRIDIS[i + 1][k]) / 255.0;
}

/* ==================================================================================== */
/* Per-triangle measures                                                                */
/* ==================================================================================== */

/* The squared lengths of the edges of (a, b, c) sorted ascending, and |cross| of the two
 * shortest edge vectors (twice the area, computed from the shortest edges for accuracy). */
static double tri_sorted(const double a[3], const double b[3], const double c[3],
                         double l2[3]) {
    const double *p[3] = {a, b, c};
    double e[3][3]; /* e[k] = edge opposite vertex k */
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++) e[k][i] = p[(k + 2) % 3][i] - p[(k + 1) % 3][i];
    double len[3];
    for (int k = 0; k < 3; k++) len[k] = e[k][0] * e[k][0] + e[k][1] * e[k][1] + e[k][2] * e[k][2];
    int o[3] = {0, 1, 2};
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2 - i; j++)
            if (len[o[j]] > len[o[j + 1]]) {
                int t = o[j];
                o[j] = o[j + 1];
                o[j + 1] = t;
            }
    for (int k = 0; k < 3; k++) l2[k] = len[o[k]];
    const double *u = e[o[0]], *v = e[o[1]];
    double cx = u[1] * v[2] - u[2] * v[1], cy = u[2] * v[0] - u[0] * v[2],
           cz = u[0] * v[1] - u[1] * v[0];
    return sqrt(cx * cx + cy * cy + cz * cz);
}

double as_tri_radius_edge(const double a[3], const double b[3], const double c[3]) {
    double l2[3];
    double cr = tri_sorted(a, b, c, l2);
    if (isnan(cr) || isnan(l2[2])) return NAN;
    if (!(cr > 0)) return INFINITY;
    /* R = l0 l1 l2 / (2 |cross|), divided by the shortest edge l0. */
    double r = sqrt(l2[1]) * sqrt(l2[2]) / (2 * cr);
    return isfinite(r) ? r : INFINITY;
}

double as_tri_aspect(const double a[3], const double b[3], const double c[3]) {
    double l2[3];
    double cr = tri_sorted(a, b, c, l2);
    if (isnan(cr) || isnan(l2[2])) return NAN;
    if (!(cr > 0)) return INFINITY;
    /* shortest altitude = 2 area / longest edge = |cross| / lmax. */
    double r = l2[2] / cr;
    return isfinite(r) ? r : INFINITY;
}

/* ==================================================================================== */
/* Bitmap font                                                                          */
/* ==================================================================================== */

typedef struct glyph {
    char c;
    unsigned char rows[GLYPH_ROWS]; /* bit 4 is the leftmost column */
} glyph;

static const glyph FONT[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E, 0x00, 0x00}},
    {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F, 0x00, 0x00}},
    {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E, 0x00, 0x00}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02, 0x00, 0x00}},
    {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E, 0x00, 0x00}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E, 0x00, 0x00}},
    {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08, 0x00, 0x00}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E, 0x00, 0x00}},
    {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C, 0x00, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C, 0x00, 0x00}},
    {'-', {0x00, 0x00, 0x00, 0x0E, 0x00, 0x00, 0x00, 0x00, 0x00}},
    {'+', {0x00, 0x04, 0x04, 0x1F, 0x04, 0x04, 0x00, 0x00, 0x00}},
    {' ', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}},
    {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02, 0x00, 0x00}},
    {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08, 0x00, 0x00}},
    {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00, 0x00, 0x00}},
    {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F, 0x00, 0x00}},
    {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00, 0x00, 0x00}},
    {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00, 0x00, 0x00}},
    {'?', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04, 0x00, 0x00}},
    {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F, 0x00, 0x00}},
    {'b', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E, 0x00, 0x00}},
    {'c', {0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E, 0x00, 0x00}},
    {'d', {0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F, 0x00, 0x00}},
    {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E, 0x00, 0x00}},
    {'f', {0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08, 0x00, 0x00}},
    {'g', {0x00, 0x00, 0x0F, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
    {'h', {0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'i', {0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00}},
    {'j', {0x02, 0x00, 0x06, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}},
    {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12, 0x00, 0x00}},
    {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E, 0x00, 0x00}},
    {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11, 0x00, 0x00}},
    {'n', {0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11, 0x00, 0x00}},
    {'o', {0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E, 0x00, 0x00}},
    {'p', {0x00, 0x00, 0x1E, 0x11, 0x11, 0x11, 0x1E, 0x10, 0x10}},
    {'q', {0x00, 0x00, 0x0F, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x01}},
    {'r', {0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10, 0x00, 0x00}},
    {'s', {0x00, 0x00, 0x0F, 0x10, 0x0E, 0x01, 0x1E, 0x00, 0x00}},
    {'t', {0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06, 0x00, 0x00}},
    {'u', {0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D, 0x00, 0x00}},
    {'v', {0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04, 0x00, 0x00}},
    {'w', {0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A, 0x00, 0x00}},
    {'x', {0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x00, 0x00}},
    {'y', {0x00, 0x00, 0x11, 0x11, 0x11, 0x11, 0x0F, 0x01, 0x0E}},
    {'z', {0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F, 0x00, 0x00}},
};

static const unsigned char *glyph_rows(char c) {
    if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
    size_t n = sizeof FONT / sizeof FONT[0], q = 0;
    for (size_t i = 0; i < n; i++) {
        if (FONT[i].c == c) return FONT[i].rows;
        if (FONT[i].c == '?') q = i;
    }
    return FONT[q].rows;
}

typedef struct canvas {
    unsigned char *rgb;
    long w, h;
} canvas;

static void fill_rect(const canvas *cv, long x0, long y0, long x1, long y1,
                      const unsigned char col[3]) {
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 > cv->w) x1 = cv->w;
    if (y1 > cv->h) y1 = cv->h;
    for (long y = y0; y < y1; y++)
        for (long x = x0; x < x1; x++) memcpy(cv->rgb + 3 * ((size_t)y * cv->w + x), col, 3);
}

/* Draw s with its top-left corner at (x, y), each font pixel a fs x fs square, glyphs
 * advancing by 6 fs. */
static void draw_text(const canvas *cv, long x, long y, const char *s, long fs,
                      const unsigned char col[3]) {
    for (; *s; s++, x += 6 * fs) {
        const unsigned char *rows = glyph_rows(*s);
        for (int r = 0; r < GLYPH_ROWS; r++)
            for (int c = 0; c < GLYPH_W; c++)
                if (rows[r] >> (GLYPH_W - 1 - c) & 1)
                    fill_rect(cv, x + c * fs, y + r * fs, x + (c + 1) * fs, y + (r + 1) * fs,
                              col);
    }
}

static long text_width(const char *s, long fs) {
    size_t n = strlen(s);
    return n ? (long)n * 6 * fs - fs : 0;
}

/* v with 4 significant digits, '.' as the decimal point whatever the locale. */
static void format_value(double v, char out[32]) {
    char buf[32];
    int n = snprintf(buf, sizeof buf, "%.4g", v);
    size_t k = 0;
    for (int i = 0; i < n && i < (int)sizeof buf - 1 && k < 31; i++) {
        char c = buf[i];
        if ((c >= '0' && c <= '9') || c == '-' || c == '+' || c == 'e') out[k++] = c;
        else if (k == 0 || out[k - 1] != '.') out[k++] = '.';
    }
    out[k] = '\0';
}

/* ==================================================================================== */
/* Legend layout                                                                        */
/* ==================================================================================== */

typedef struct legend {
    int on;
    long fs;              /* font scale */
    long col_w;           /* width of the legend column (reserved on the right) */
    long bar_x, bar_y, bar_w, bar_h;
    int single;           /* vmin == vmax: one label, uniform bar */
    char top[32], mid[32], bot[32];
    const char *title;
} legend;

static void legend_layout(legend *lg, const as_render_params *p, int have_range, double vmin,
                          double vmax) {
    memset(lg, 0, sizeof *lg);
    if (!p->legend || !have_range) return;
    long W = (long)p->width, H = (long)p->height;
    long mn = W < H ? W : H;
    lg->fs = (long)floor(mn / 400.0 + 0.5);
    if (lg->fs < 1) lg->fs = 1;
    long adv = 6 * lg->fs, gh = GLYPH_H * lg->fs, pad = 2 * adv;
    lg->single = !(vmax > vmin);
    format_value(vmax, lg->top);
    format_value(0.5 * vmin + 0.5 * vmax, lg->mid);
    format_value(vmin, lg->bot);
    long numw = text_width(lg->top, lg->fs);
    long w2 = text_width(lg->mid, lg->fs), w3 = text_width(lg->bot, lg->fs);
    if (w2 > numw) numw = w2;
    if (w3 > numw) numw = w3;
    lg->bar_w = 2 * adv;
    lg->col_w = pad + lg->bar_w + adv + numw + pad;
    lg->title = p->label && *p->label ? p->label : NULL;
    if (lg->title) {
        long tw = text_width(lg->title, lg->fs) + 2 * pad;
        if (tw > lg->col_w) lg->col_w = tw;
    }
    if (lg->col_w * 3 > W || H < 120) {
        lg->col_w = 0;
        return;
    }
    lg->bar_h = (long)floor(0.6 * H);
    lg->bar_y = (H - lg->bar_h) / 2 + gh;
    lg->bar_x = W - lg->col_w + pad;
    lg->on = 1;
}

static void legend_draw(const legend *lg, const canvas *cv) {
    if (!lg->on) return;
    long fs = lg->fs, gh = GLYPH_H * fs, adv = 6 * fs;
    long fw = fs / 2 > 0 ? fs / 2 : 1; /* frame width */
    for (long r = 0; r < lg->bar_h; r++) {
        double t = lg->single ? 0.5 : 1 - (r + 0.5) / (double)lg->bar_h;
        double c[3];
        as_render_colormap(t, c);
        unsigned char b[3];
        for (int k = 0; k < 3; k++) b[k] = (unsigned char)floor(255 * c[k] + 0.5);
        fill_rect(cv, lg->bar_x, lg->bar_y + r, lg->bar_x + lg->bar_w, lg->bar_y + r + 1, b);
    }
    long x0 = lg->bar_x - fw, y0 = lg->bar_y - fw, x1 = lg->bar_x + lg->bar_w + fw,
         y1 = lg->bar_y + lg->bar_h + fw;
    fill_rect(cv, x0, y0, x1, lg->bar_y, TEXT);
    fill_rect(cv, x0, lg->bar_y + lg->bar_h, x1, y1, TEXT);
    fill_rect(cv, x0, lg->bar_y, lg->bar_x, lg->bar_y + lg->bar_h, TEXT);
    fill_rect(cv, lg->bar_x + lg->bar_w, lg->bar_y, x1, lg->bar_y + lg->bar_h, TEXT);
    long tx = lg->bar_x + lg->bar_w + adv;
    long ticks[3] = {lg->bar_y, lg->bar_y + lg->bar_h / 2, lg->bar_y + lg->bar_h};
    const char *text[3] = {lg->top, lg->mid, lg->bot};
    for (int i = 0; i < 3; i++) {
        if (lg->single && i != 1) continue;
        fill_rect(cv, x1, ticks[i] - fw / 2 - (fw & 1), x1 + adv / 2,
                  ticks[i] + fw / 2, TEXT);
        draw_text(cv, tx, ticks[i] - gh / 2, text[i], fs, TEXT);
    }
    if (lg->title) draw_text(cv, lg->bar_x, lg->bar_y - 2 * gh - fw, lg->title, fs, TEXT);
}

/* ==================================================================================== */
/* Rasterization                                                                        */
/* ==================================================================================== */

/*
 * An edge line of a triangle, set up from the lexicographically smaller (x, then y) of
 * its two endpoints: value(x, y) = sgn * (dx (y - ay) - dy (x - ax)), twice the signed
 * area of (a, b, p) times the triangle's orientation sign. Both triangles of a shared
 * edge compute the same products from the same base point and differ only in sgn, so
 * their values at any sample are exactly opposite: no sample falls between them.
 */
typedef struct edge_eq {
    double ax, ay, dx, dy, sgn;
} edge_eq;

static inline void edge_setup(edge_eq *e, const double *a, const double *b, double sgn) {
    if (a[0] < b[0] || (a[0] == b[0] && a[1] < b[1])) {
        e->ax = a[0], e->ay = a[1], e->dx = b[0] - a[0], e->dy = b[1] - a[1], e->sgn = sgn;
    } else {
        e->ax = b[0], e->ay = b[1], e->dx = a[0] - b[0], e->dy = a[1] - b[1], e->sgn = -sgn;
    }
}

static inline double edge_value(const edge_eq *e, double x, double y) {
    return e->sgn * (e->dx * (y - e->ay) - e->dy * (x - e->ax));
}

/* Per triangle: shaded colour and edge opacity; first and last sample row, or culled. */
typedef struct rtri {
    float col[3];
    float alpha;
} rtri;

typedef struct rstate {
    const as_render_params *p;
    const int32_t *tri;
    double *proj;     /* 3 per vertex: x, y in samples; depth (larger is nearer) */
    rtri *rt;
    int32_t *row0, *row1; /* sample rows of each triangle; row0 > row1: culled */
    long ws, hs;      /* image size in samples */
    int ss;
    double bg[3];
    /* the band */
    long band_rows;   /* sample rows per band */
    double *depth;
    int32_t *id;
} rstate;

/*
 * Rasterize triangle t into the band of sample rows [jb0, jb1): every sample inside or
 * on the border takes the triangle when it is nearer than what the sample holds (ties:
 * the smaller index).
 * design: per row, the span where the three edge values are >= 0 is estimated by
 *   solving each edge for x and widened by one sample; within it every sample is tested
 *   exactly, so the estimate only saves work. Depth: barycentric interpolation.
 */
static void raster_tri(rstate *r, int32_t t, long jb0, long jb1) {
    const int32_t *v = r->tri + 3 * (size_t)t;
    const double *p[3] = {r->proj + 3 * (size_t)v[0], r->proj + 3 * (size_t)v[1],
                          r->proj + 3 * (size_t)v[2]};
    double area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) -
                  (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
    double s = area > 0 ? 1 : -1;
    edge_eq e[3]; /* e[k]: the edge opposite vertex k */
    for (int k = 0; k < 3; k++) edge_setup(&e[k], p[(k + 1) % 3], p[(k + 2) % 3], s);
    long j0 = r->row0[t] > jb0 ? r->row0[t] : jb0;
    long j1 = r->row1[t] < jb1 - 1 ? r->row1[t] : jb1 - 1;
    double xmin = fmin(p[0][0], fmin(p[1][0], p[2][0]));
    double xmax = fmax(p[0][0], fmax(p[1][0], p[2][0]));
    long i0 = (long)ceil(xmin - 0.5), i1 = (long)floor(xmax - 0.5);
    if (i0 < 0) i0 = 0;
    if (i1 > r->ws - 1) i1 = r->ws - 1;
    const double z0 = p[0][2], z1 = p[1][2], z2 = p[2][2];
    for (long j = j0; j <= j1; j++) {
        double y = j + 0.5, lo = xmin, hi = xmax;
        for (int k = 0; k < 3; k++) {
            double k_dy = e[k].sgn * e[k].dy;
            double ry = e[k].dx * (y - e[k].ay);
            if (k_dy == 0) {
                if (e[k].sgn * ry < 0) lo = INFINITY;
                continue;
            }
            double xc = e[k].ax + ry / e[k].dy; /* where the edge value is 0 */
            if (k_dy > 0) hi = fmin(hi, xc);
            else lo = fmax(lo, xc);
        }
        if (!(lo <= hi + 2)) continue;
        long a = (long)ceil(lo - 0.5) - 1, b = (long)floor(hi - 0.5) + 1;
        if (a < i0) a = i0;
        if (b > i1) b = i1;
        double *drow = r->depth + (size_t)(j - jb0) * r->ws;
        int32_t *irow = r->id + (size_t)(j - jb0) * r->ws;
        for (long i = a; i <= b; i++) {
            double x = i + 0.5;
            double w0 = edge_value(&e[0], x, y);
            if (w0 < 0) continue;
            double w1 = edge_value(&e[1], x, y);
            if (w1 < 0) continue;
            double w2 = edge_value(&e[2], x, y);
            if (w2 < 0) continue;
            double sum = w0 + w1 + w2;
            double z = sum > 0 ? (w0 * z0 + w1 * z1 + w2 * z2) / sum : z0;
            int32_t old = irow[i];
            if (old < 0 || z > drow[i] || (z == drow[i] && t < old)) {
                drow[i] = z;
                irow[i] = t;
            }
        }
    }
}

/* The edge lines of the last triangle seen by the resolve pass. */
typedef struct edge_cache {
    int32_t id;
    edge_eq e[3];
    double inv_len[3]; /* 1 / length (samples), 0 for a zero-length edge */
} edge_cache;

/* Distance in pixels from the sample (x, y) to the nearest edge line of triangle t. */
static double edge_distance(const rstate *r, edge_cache *ec, int32_t t, double x, double y) {
    if (ec->id != t) {
        const int32_t *v = r->tri + 3 * (size_t)t;
        const double *p[3] = {r->proj + 3 * (size_t)v[0], r->proj + 3 * (size_t)v[1],
                              r->proj + 3 * (size_t)v[2]};
        for (int k = 0; k < 3; k++) {
            edge_setup(&ec->e[k], p[(k + 1) % 3], p[(k + 2) % 3], 1);
            double l = hypot(ec->e[k].dx, ec->e[k].dy);
            ec->inv_len[k] = l > 0 ? 1 / l : 0;
        }
        ec->id = t;
    }
    double d = INFINITY;
    for (int k = 0; k < 3; k++) {
        if (ec->inv_len[k] == 0) continue;
        double e = fabs(edge_value(&ec->e[k], x, y)) * ec->inv_len[k];
        if (e < d) d = e;
    }
    return d / r->ss; /* pixels */
}

/* Average the samples of output rows [y0, y1) (band starting at sample row jb0). */
static void resolve(const rstate *r, long y0, long y1, long jb0, unsigned char *rgb) {
    int ss = r->ss;
    double inv = 1.0 / (ss * ss);
    edge_cache ec;
    memset(&ec, 0, sizeof ec);
    ec.id = -1;
    long W = (long)r->p->width;
    for (long y = y0; y < y1; y++) {
        for (long x = 0; x < W; x++) {
            double acc[3] = {0, 0, 0};
            for (int sj = 0; sj < ss; sj++) {
                long j = y * ss + sj;
                const int32_t *irow = r->id + (size_t)(j - jb0) * r->ws;
                for (int si = 0; si < ss; si++) {
                    long i = x * ss + si;
                    int32_t t = irow[i];
                    if (t < 0) {
                        for (int k = 0; k < 3; k++) acc[k] += r->bg[k];
                        continue;
                    }
                    const rtri *rt = r->rt + t;
                    double col[3] = {rt->col[0], rt->col[1], rt->col[2]};
                    if (rt->alpha > 0) {
                        double d = edge_distance(r, &ec, t, i + 0.5, j + 0.5);
                        /* coverage ramps over one sample across the line's border */
                        double cov = (EDGE_HALF - d) * ss + 0.5;
                        if (cov > 0) {
                            if (cov > 1) cov = 1;
                            double a = rt->alpha * cov;
                            double lum = 0.2126 * col[0] + 0.7152 * col[1] + 0.0722 * col[2];
                            for (int k = 0; k < 3; k++) {
                                double e = lum > 0.3 ? 0.25 * col[k] : col[k] + 0.55 * (1 - col[k]);
                                col[k] = (1 - a) * col[k] + a * e;
                            }
                        }
                    }
                    for (int k = 0; k < 3; k++) acc[k] += col[k];
                }
            }
            unsigned char *o = rgb + 3 * ((size_t)y * W + x);
            for (int k = 0; k < 3; k++) {
                double c = acc[k] * inv * 255;
                c = c < 0 ? 0 : (c > 255 ? 255 : c);
                o[k] = (unsigned char)floor(c + 0.5);
            }
        }
    }
}

/* ==================================================================================== */
/* as_render                                                                            */
/* ==================================================================================== */

anistar_status as_render_params_check(anistar_context *ctx, const as_render_params *p) {
    if (!p) return as_fail(ctx, ANISTAR_EINVAL, "render: NULL parameters");
    if (p->width < 1 || p->width > AS_RENDER_MAX_SIDE || p->height < 1 ||
        p->height > AS_RENDER_MAX_SIDE)
        return as_fail(ctx, ANISTAR_EINVAL, "render: image size %ux%u outside [1, %u]",
                       (unsigned)p->width, (unsigned)p->height, AS_RENDER_MAX_SIDE);
    if (!isfinite(p->azimuth) || !isfinite(p->elevation))
        return as_fail(ctx, ANISTAR_EINVAL, "render: view angles must be finite");
    if (p->up < 0 || p->up > 2)
        return as_fail(ctx, ANISTAR_EINVAL, "render: up axis %d (0, 1 or 2 expected)", p->up);
    if (p->supersample < 1 || p->supersample > 4)
        return as_fail(ctx, ANISTAR_EINVAL, "render: supersampling %d outside [1, 4]",
                       p->supersample);
    if (!(p->ambient >= 0 && p->ambient <= 1 && p->diffuse >= 0 && p->diffuse <= 1))
        return as_fail(ctx, ANISTAR_EINVAL, "render: ambient and diffuse must be in [0, 1]");
    int a = isnan(p->vmin), b = isnan(p->vmax);
    if (a != b)
        return as_fail(ctx, ANISTAR_EINVAL, "render: give both ends of the colour range or none");
    if (!a && !(isfinite(p->vmin) && isfinite(p->vmax) && p->vmin < p->vmax))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "render: colour range [%g, %g] must be finite with min < max", p->vmin,
                       p->vmax);
    return ANISTAR_OK;
}

typedef struct rbuf {
    double *proj;
    rtri *rt;
    int32_t *row0, *row1, *order, *start, *cursor, *active;
    double *depth;
    int32_t *id;
    size_t nv, nt, nbands, nband_samples;
} rbuf;

static void rbuf_free(anistar_context *ctx, rbuf *b) {
    as_free(ctx, b->proj, 3 * b->nv * sizeof(double));
    as_free(ctx, b->rt, b->nt * sizeof(rtri));
    as_free(ctx, b->row0, b->nt * sizeof(int32_t));
    as_free(ctx, b->row1, b->nt * sizeof(int32_t));
    as_free(ctx, b->order, b->nt * sizeof(int32_t));
    as_free(ctx, b->active, b->nt * sizeof(int32_t));
    as_free(ctx, b->start, (b->nbands + 1) * sizeof(int32_t));
    as_free(ctx, b->cursor, b->nbands * sizeof(int32_t));
    as_free(ctx, b->depth, b->nband_samples * sizeof(double));
    as_free(ctx, b->id, b->nband_samples * sizeof(int32_t));
}

anistar_status as_render(anistar_context *ctx, const as_render_params *p, size_t nv,
                         const double *xyz, size_t nt, const int32_t *tri,
                         const double *values, unsigned char *rgb) {
    if (!p || !rgb) return as_fail(ctx, ANISTAR_EINVAL, "render: NULL parameters or image");
    anistar_status st = as_render_params_check(ctx, p);
    if (st) return st;
    if ((nv && !xyz) || (nt && !tri))
        return as_fail(ctx, ANISTAR_EINVAL, "render: NULL coordinates or triangles");
    if (nv > (size_t)INT32_MAX || nt > (size_t)INT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "render: too many vertices or triangles");
    for (size_t i = 0; i < 3 * nv; i++)
        if (!isfinite(xyz[i]))
            return as_fail(ctx, ANISTAR_EINVAL, "render: vertex %zu has a non-finite coordinate",
                           i / 3);
    for (size_t i = 0; i < 3 * nt; i++)
        if (tri[i] < 0 || (size_t)tri[i] >= nv)
            return as_fail(ctx, ANISTAR_EINVAL,
                           "render: triangle %zu: vertex index %ld out of range [0, %zu)", i / 3,
                           (long)tri[i], nv);

    const long W = (long)p->width, H = (long)p->height;
    const int ss = p->supersample;
    rstate r;
    memset(&r, 0, sizeof r);
    r.p = p;
    r.tri = tri;
    r.ss = ss;
    r.ws = W * ss;
    r.hs = H * ss;
    for (int k = 0; k < 3; k++) r.bg[k] = p->background[k] / 255.0;

    /* Colour range. */
    double vmin = p->vmin, vmax = p->vmax;
    int have_range = !isnan(vmin);
    if (!have_range && values) {
        for (size_t t = 0; t < nt; t++) {
            double v = values[t];
            if (!isfinite(v)) continue;
            if (!have_range) {
                vmin = vmax = v;
                have_range = 1;
            } else {
                if (v < vmin) vmin = v;
                if (v > vmax) vmax = v;
            }
        }
    }
    legend lg;
    legend_layout(&lg, p, have_range && values != NULL, vmin, vmax);

    /* View frame in the permuted axes (X, Y, Z), Z = up. */
    static const int perm[3][3] = {{1, 2, 0}, {2, 0, 1}, {0, 1, 2}};
    const int *pm = perm[p->up];
    double az = p->azimuth * (AS_PI / 180), el = p->elevation * (AS_PI / 180);
    double ca = cos(az), sa = sin(az), ce = cos(el), se = sin(el);
    const double right[3] = {-sa, ca, 0}, up[3] = {-se * ca, -se * sa, ce},
                 dir[3] = {ce * ca, ce * sa, se};
    double light[3];
    {
        const double lv[3] = {-0.35, 0.45, 1.0};
        double ln = sqrt(lv[0] * lv[0] + lv[1] * lv[1] + lv[2] * lv[2]);
        for (int k = 0; k < 3; k++)
            light[k] = (lv[0] * right[k] + lv[1] * up[k] + lv[2] * dir[k]) / ln;
    }

    rbuf b;
    memset(&b, 0, sizeof b);
    b.nv = nv;
    b.nt = nt;
    if (nt == 0) {
        /* Nothing to rasterize: background and (when a range is given) the legend. */
        for (size_t i = 0; i < (size_t)W * (size_t)H; i++) memcpy(rgb + 3 * i, p->background, 3);
        canvas cv = {rgb, W, H};
        legend_draw(&lg, &cv);
        return ANISTAR_OK;
    }

    b.proj = as_alloc_array(ctx, 3 * nv, sizeof(double));
    b.rt = as_alloc_array(ctx, nt, sizeof(rtri));
    b.row0 = as_alloc_array(ctx, nt, sizeof(int32_t));
    b.row1 = as_alloc_array(ctx, nt, sizeof(int32_t));
    b.order = as_alloc_array(ctx, nt, sizeof(int32_t));
    b.active = as_alloc_array(ctx, nt, sizeof(int32_t));
    long band_rows = BAND_SAMPLES / r.ws; /* sample rows per band, a multiple of ss */
    band_rows -= band_rows % ss;
    if (band_rows < ss) band_rows = ss;
    if (band_rows > r.hs) band_rows = r.hs;
    b.nbands = (size_t)((r.hs + band_rows - 1) / band_rows);
    b.nband_samples = (size_t)band_rows * (size_t)r.ws;
    b.start = as_alloc_array(ctx, b.nbands + 1, sizeof(int32_t));
    b.cursor = as_alloc_array(ctx, b.nbands, sizeof(int32_t));
    b.depth = as_alloc_array(ctx, b.nband_samples, sizeof(double));
    b.id = as_alloc_array(ctx, b.nband_samples, sizeof(int32_t));
    if (!b.proj || !b.rt || !b.row0 || !b.row1 || !b.order || !b.active || !b.start ||
        !b.cursor || !b.depth || !b.id) {
        rbuf_free(ctx, &b);
        return as_fail(ctx, ANISTAR_ENOMEM, "render: out of memory (%zu vertices, %zu "
                       "triangles, %ldx%ld samples)", nv, nt, r.ws, r.hs);
    }
    r.proj = b.proj;
    r.rt = b.rt;
    r.row0 = b.row0;
    r.row1 = b.row1;
    r.band_rows = band_rows;
    r.depth = b.depth;
    r.id = b.id;

    /* Project (screen right, screen up, depth) and fit the used vertices. */
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t i = 0; i < nv; i++) {
        const double *q = xyz + 3 * i;
        const double P[3] = {q[pm[0]], q[pm[1]], q[pm[2]]};
        double *o = b.proj + 3 * i;
        o[0] = P[0] * right[0] + P[1] * right[1] + P[2] * right[2];
        o[1] = P[0] * up[0] + P[1] * up[1] + P[2] * up[2];
        o[2] = P[0] * dir[0] + P[1] * dir[1] + P[2] * dir[2];
    }
    for (size_t i = 0; i < 3 * nt; i++) {
        const double *o = b.proj + 3 * (size_t)tri[i];
        for (int k = 0; k < 2; k++) {
            if (o[k] < lo[k]) lo[k] = o[k];
            if (o[k] > hi[k]) hi[k] = o[k];
        }
    }
    int finite = isfinite(hi[0] - lo[0]) && isfinite(hi[1] - lo[1]);
    for (size_t i = 0; i < nv && finite; i++)
        finite = isfinite(b.proj[3 * i]) && isfinite(b.proj[3 * i + 1]) &&
                 isfinite(b.proj[3 * i + 2]);
    if (!finite) {
        rbuf_free(ctx, &b);
        return as_fail(ctx, ANISTAR_EINVAL,
                       "render: the coordinates are too large to project (overflow)");
    }
    double m = floor(0.05 * (W < H ? W : H));
    double aw = W - lg.col_w - 2 * m, ah = H - 2 * m;
    if (aw < 1) aw = 1;
    if (ah < 1) ah = 1;
    double bw = hi[0] - lo[0], bh = hi[1] - lo[1], scale;
    if (bw > 0 && bh > 0) scale = fmin(aw / bw, ah / bh);
    else if (bw > 0) scale = aw / bw;
    else if (bh > 0) scale = ah / bh;
    else scale = 1;
    double cx = m + 0.5 * aw, cy = m + 0.5 * ah;
    double mx = 0.5 * (lo[0] + hi[0]), my = 0.5 * (lo[1] + hi[1]);
    for (size_t i = 0; i < nv; i++) {
        double *o = b.proj + 3 * i;
        o[0] = (cx + scale * (o[0] - mx)) * ss;
        o[1] = (cy - scale * (o[1] - my)) * ss;
    }

    /* Per triangle: shading, edge fade, rows; bucket by first band. */
    for (size_t i = 0; i <= b.nbands; i++) b.start[i] = 0;
    for (size_t t = 0; t < nt; t++) {
        const int32_t *v = tri + 3 * t;
        b.row0[t] = 1;
        b.row1[t] = 0; /* culled unless set below */
        const double *a = b.proj + 3 * (size_t)v[0], *bb = b.proj + 3 * (size_t)v[1],
                     *c = b.proj + 3 * (size_t)v[2];
        double area = (bb[0] - a[0]) * (c[1] - a[1]) - (bb[1] - a[1]) * (c[0] - a[0]);
        if (!(area != 0)) continue;
        double ymin = fmin(a[1], fmin(bb[1], c[1])), ymax = fmax(a[1], fmax(bb[1], c[1]));
        double xmin = fmin(a[0], fmin(bb[0], c[0])), xmax = fmax(a[0], fmax(bb[0], c[0]));
        double j0 = ceil(ymin - 0.5), j1 = floor(ymax - 0.5);
        double i0 = ceil(xmin - 0.5), i1 = floor(xmax - 0.5);
        if (j0 < 0) j0 = 0;
        if (j1 > r.hs - 1) j1 = (double)(r.hs - 1);
        if (i0 < 0) i0 = 0;
        if (i1 > r.ws - 1) i1 = (double)(r.ws - 1);
        if (j0 > j1 || i0 > i1) continue; /* covers no sample */
        /* 3D normal, turned toward the viewer. */
        double P[3][3];
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++) P[k][d] = xyz[3 * (size_t)v[k] + (size_t)pm[d]];
        double e1[3], e2[3], n[3];
        for (int d = 0; d < 3; d++) {
            e1[d] = P[1][d] - P[0][d];
            e2[d] = P[2][d] - P[0][d];
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double ndl = 0;
        int front = 1;
        if (nl > 0 && isfinite(nl)) {
            double nd = (n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2]) / nl;
            front = nd >= 0;
            ndl = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / nl;
            if (!front) ndl = -ndl;
        }
        double inten = p->ambient + p->diffuse * (ndl > 0 ? ndl : 0);
        double base[3];
        if (values) {
            double val = values[t], tt;
            if (isnan(val)) tt = NAN;
            else if (val == INFINITY) tt = 1;
            else if (val == -INFINITY) tt = 0;
            else if (!(vmax > vmin)) tt = 0.5;
            else tt = (val - vmin) / (vmax - vmin);
            as_render_colormap(tt, base);
        } else {
            memcpy(base, PLAIN, sizeof base);
        }
        if (!front)
            for (int k = 0; k < 3; k++) base[k] = 0.5 * base[k] + 0.5 * BRICK[k];
        for (int k = 0; k < 3; k++) {
            double cval = base[k] * inten;
            b.rt[t].col[k] = (float)(cval > 1 ? 1 : cval);
        }
        float alpha = 0;
        if (p->edges) {
            double l0 = hypot(bb[0] - c[0], bb[1] - c[1]), l1 = hypot(c[0] - a[0], c[1] - a[1]),
                   l2 = hypot(a[0] - bb[0], a[1] - bb[1]);
            double lmax = fmax(l0, fmax(l1, l2));
            double h = fabs(area) / lmax / ss; /* shortest altitude, pixels */
            double f = (h - FADE_LO) / (FADE_HI - FADE_LO);
            f = f < 0 ? 0 : (f > 1 ? 1 : f);
            alpha = (float)(EDGE_ALPHA * f);
        }
        b.rt[t].alpha = alpha;
        b.row0[t] = (int32_t)j0;
        b.row1[t] = (int32_t)j1;
        b.start[(size_t)(b.row0[t] / band_rows) + 1]++;
    }
    for (size_t i = 0; i < b.nbands; i++) b.start[i + 1] += b.start[i];
    /* Stable counting sort by first band (cursor: the next free slot of each band). */
    for (size_t i = 0; i < b.nbands; i++) b.cursor[i] = b.start[i];
    for (size_t t = 0; t < nt; t++) {
        if (b.row0[t] > b.row1[t]) continue;
        size_t band = (size_t)(b.row0[t] / band_rows);
        b.order[b.cursor[band]++] = (int32_t)t;
    }

    /* Bands. */
    canvas cv = {rgb, W, H};
    size_t nactive = 0;
    for (size_t band = 0; band < b.nbands; band++) {
        long jb0 = (long)band * band_rows, jb1 = jb0 + band_rows;
        if (jb1 > r.hs) jb1 = r.hs;
        size_t k = 0;
        for (size_t i = 0; i < nactive; i++)
            if (b.row1[b.active[i]] >= jb0) b.active[k++] = b.active[i];
        nactive = k;
        for (int32_t i = b.start[band]; i < b.start[band + 1]; i++)
            b.active[nactive++] = b.order[i];
        size_t ns = (size_t)(jb1 - jb0) * (size_t)r.ws;
        for (size_t i = 0; i < ns; i++) b.id[i] = -1;
        for (size_t i = 0; i < nactive; i++) raster_tri(&r, b.active[i], jb0, jb1);
        resolve(&r, jb0 / ss, jb1 / ss, jb0, rgb);
    }
    legend_draw(&lg, &cv);
    rbuf_free(ctx, &b);
    return ANISTAR_OK;
}
