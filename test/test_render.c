/*
 * test_render.c — the PNG encoder (lib/io/png.c), the rasterizer (lib/io/render.c), the
 * public rendering API (anistar_render_*, anistar_triangle_values) and `anistar render`.
 *
 * The PNG files are checked by an independent decoder written here: chunk CRCs with a
 * bitwise CRC-32 (no table), the zlib header and Adler-32 (computed byte by byte with a
 * modulo each step), and an inflater that builds canonical Huffman decoders from code
 * lengths (RFC 1951 3.2.2) and derives the length/distance tables from their rule, so it
 * shares no code and no table with the encoder. The decoded scanlines must equal the
 * framebuffer byte for byte.
 */
#include "test_util.h"

#include "io/meshio.h"
#include "io/png.h"
#include "io/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"
#define KNOT AS_TEST_DATA_DIR "/knot1.off"

/* ==================================================================================== */
/* Independent checksums                                                                */
/* ==================================================================================== */

static uint32_t crc_bitwise(const unsigned char *p, size_t n) {
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    }
    return ~c;
}

static uint32_t adler_slow(const unsigned char *p, size_t n) {
    uint32_t a = 1, b = 0;
    for (size_t i = 0; i < n; i++) {
        a = (a + p[i]) % 65521u;
        b = (b + a) % 65521u;
    }
    return b << 16 | a;
}

static uint32_t be32(const unsigned char *p) {
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

/* ==================================================================================== */
/* Independent inflater                                                                 */
/* ==================================================================================== */

typedef struct bitin {
    const unsigned char *p;
    size_t n, pos;
    unsigned bit;
    int err;
} bitin;

static unsigned get_bit(bitin *b) {
    if (b->pos >= b->n) {
        b->err = 1;
        return 0;
    }
    unsigned v = (b->p[b->pos] >> b->bit) & 1u;
    if (++b->bit == 8) {
        b->bit = 0;
        b->pos++;
    }
    return v;
}

static unsigned get_bits(bitin *b, unsigned n) {
    unsigned v = 0;
    for (unsigned i = 0; i < n; i++) v |= get_bit(b) << i;
    return v;
}

/* A canonical Huffman code: count[len] codes of each length, symbols by (length, value). */
typedef struct huff {
    int count[16];
    int sym[320];
} huff;

static void huff_build(huff *h, const unsigned char *lens, int n) {
    memset(h, 0, sizeof *h);
    for (int s = 0; s < n; s++) h->count[lens[s]]++;
    h->count[0] = 0;
    int offs[16];
    offs[1] = 0;
    for (int l = 1; l < 15; l++) offs[l + 1] = offs[l] + h->count[l];
    for (int s = 0; s < n; s++)
        if (lens[s]) h->sym[offs[lens[s]]++] = s;
}

/* Read one symbol, most significant code bit first; -1 on a bad code. */
static int huff_decode(bitin *b, const huff *h) {
    int code = 0, first = 0, index = 0;
    for (int len = 1; len < 16; len++) {
        code |= (int)get_bit(b);
        int cnt = h->count[len];
        if (code - first < cnt) return h->sym[index + code - first];
        index += cnt;
        first = (first + cnt) << 1;
        code <<= 1;
    }
    return -1;
}

typedef struct inflate_stats {
    int stored, fixed, dynamic;
} inflate_stats;

/* Inflate raw deflate data into out[cap]; returns the size, or -1 on an error. Only
 * stored and fixed-Huffman blocks are accepted (the encoder writes nothing else). */
static long inflate_raw(bitin *b, unsigned char *out, size_t cap, inflate_stats *stats) {
    /* Length and distance tables from their rule (RFC 1951 3.2.5). */
    unsigned lbase[29], lextra[29], dbase[30], dextra[30];
    lbase[0] = 3;
    for (int i = 0; i < 28; i++) {
        lextra[i] = i < 8 ? 0 : (unsigned)(i / 4 - 1);
        lbase[i + 1] = lbase[i] + (1u << lextra[i]);
    }
    lbase[28] = 258;
    lextra[28] = 0;
    dbase[0] = 1;
    for (int i = 0; i < 30; i++) {
        dextra[i] = i < 4 ? 0 : (unsigned)(i / 2 - 1);
        if (i < 29) dbase[i + 1] = dbase[i] + (1u << dextra[i]);
    }
    unsigned char ll[288], dl[30];
    for (int s = 0; s < 288; s++) ll[s] = s < 144 ? 8 : s < 256 ? 9 : s < 280 ? 7 : 8;
    for (int s = 0; s < 30; s++) dl[s] = 5;
    huff hl, hd;
    huff_build(&hl, ll, 288);
    huff_build(&hd, dl, 30);
    size_t n = 0;
    for (;;) {
        unsigned final = get_bit(b), type = get_bits(b, 2);
        if (b->err) return -1;
        if (type == 0) {
            stats->stored++;
            if (b->bit) {
                b->bit = 0;
                b->pos++;
            }
            if (b->pos + 4 > b->n) return -1;
            unsigned len = b->p[b->pos] | (unsigned)b->p[b->pos + 1] << 8;
            unsigned nlen = b->p[b->pos + 2] | (unsigned)b->p[b->pos + 3] << 8;
            b->pos += 4;
            if ((len ^ 0xFFFFu) != nlen || b->pos + len > b->n || n + len > cap) return -1;
            memcpy(out + n, b->p + b->pos, len);
            b->pos += len;
            n += len;
        } else if (type == 1) {
            stats->fixed++;
            for (;;) {
                int s = huff_decode(b, &hl);
                if (s < 0 || b->err) return -1;
                if (s < 256) {
                    if (n >= cap) return -1;
                    out[n++] = (unsigned char)s;
                } else if (s == 256) {
                    break;
                } else {
                    s -= 257;
                    if (s >= 29) return -1;
                    unsigned len = lbase[s] + get_bits(b, lextra[s]);
                    int d = huff_decode(b, &hd);
                    if (d < 0 || d >= 30) return -1;
                    unsigned dist = dbase[d] + get_bits(b, dextra[d]);
                    if (b->err || dist > n || n + len > cap) return -1;
                    for (unsigned k = 0; k < len; k++, n++) out[n] = out[n - dist];
                }
            }
        } else {
            if (type == 2) stats->dynamic++;
            return -1;
        }
        if (final) break;
    }
    /* Trailing zlib bytes start on a byte boundary. */
    if (b->bit) {
        b->bit = 0;
        b->pos++;
    }
    return (long)n;
}

/* ==================================================================================== */
/* Independent PNG decoder                                                              */
/* ==================================================================================== */

typedef struct png_info {
    uint32_t w, h;
    int channels;
    unsigned char *pix; /* w * h * channels (test_malloc) */
    inflate_stats stats;
    int idat_chunks;
} png_info;

/* Decode an 8-bit RGB/RGBA PNG as the encoder writes it; every property is asserted. */
static void png_decode(const unsigned char *f, size_t size, png_info *info) {
    memset(info, 0, sizeof *info);
    static const unsigned char sig[8] = {137, 80, 78, 71, 13, 10, 26, 10};
    assert_true(size >= 8 + 25 + 12);
    assert_memory_equal(f, sig, 8);
    size_t pos = 8, zcap = 0, zn = 0;
    unsigned char *z = NULL;
    int seen_ihdr = 0, seen_iend = 0;
    while (pos < size) {
        assert_true(pos + 12 <= size);
        uint32_t len = be32(f + pos);
        assert_true(len <= size - pos - 12);
        const unsigned char *type = f + pos + 4, *data = f + pos + 8;
        uint32_t crc = be32(f + pos + 8 + len);
        if (crc != crc_bitwise(type, 4 + (size_t)len))
            fail_msg("chunk %.4s at %zu: bad CRC", (const char *)type, pos);
        assert_false(seen_iend);
        if (!memcmp(type, "IHDR", 4)) {
            assert_false(seen_ihdr);
            assert_int_equal(pos, 8);
            assert_int_equal(len, 13);
            info->w = be32(data);
            info->h = be32(data + 4);
            assert_true(info->w >= 1 && info->h >= 1);
            assert_int_equal(data[8], 8); /* bit depth */
            assert_true(data[9] == 2 || data[9] == 6);
            info->channels = data[9] == 2 ? 3 : 4;
            assert_int_equal(data[10], 0);
            assert_int_equal(data[11], 0);
            assert_int_equal(data[12], 0);
            seen_ihdr = 1;
        } else if (!memcmp(type, "IDAT", 4)) {
            assert_true(seen_ihdr);
            info->idat_chunks++;
            if (zn + len > zcap) {
                zcap = 2 * (zn + len);
                z = test_realloc(z, zcap);
            }
            memcpy(z + zn, data, len);
            zn += len;
        } else if (!memcmp(type, "IEND", 4)) {
            assert_int_equal(len, 0);
            seen_iend = 1;
        } else {
            fail_msg("unexpected chunk %.4s", (const char *)type);
        }
        pos += 12 + (size_t)len;
    }
    assert_true(seen_iend);
    assert_int_equal(pos, size);
    /* zlib wrapper */
    assert_true(zn >= 6);
    assert_int_equal(z[0] & 0x0F, 8);           /* deflate */
    assert_true((z[0] >> 4) <= 7);              /* window <= 32K */
    assert_int_equal((z[0] * 256 + z[1]) % 31, 0);
    assert_int_equal(z[1] & 0x20, 0);           /* no preset dictionary */
    size_t rb = (size_t)info->w * (size_t)info->channels, raw_n = (rb + 1) * info->h;
    unsigned char *raw = test_malloc(raw_n + 1);
    bitin b = {z + 2, zn - 2, 0, 0, 0};
    long got = inflate_raw(&b, raw, raw_n + 1, &info->stats);
    assert_int_equal(got, (long)raw_n);
    assert_int_equal(b.pos + 4, b.n); /* exactly the Adler-32 follows */
    assert_int_equal(be32(b.p + b.pos), adler_slow(raw, raw_n));
    info->pix = test_malloc(rb * info->h);
    for (uint32_t r = 0; r < info->h; r++) {
        assert_int_equal(raw[r * (rb + 1)], 0); /* filter None */
        memcpy(info->pix + r * rb, raw + r * (rb + 1) + 1, rb);
    }
    test_free(raw);
    test_free(z);
}

static void png_info_free(png_info *info) {
    test_free(info->pix);
    info->pix = NULL;
}

/* Encode in memory, decode here, compare with the framebuffer. Returns the file size. */
static size_t png_roundtrip(anistar_context *ctx, const unsigned char *pix, uint32_t w,
                            uint32_t h, int ch, as_png_compression comp, inflate_stats *stats) {
    unsigned char *f = NULL;
    size_t n = 0;
    assert_int_equal(as_png_encode_mem(ctx, pix, w, h, ch, comp, &f, &n), ANISTAR_OK);
    png_info info;
    png_decode(f, n, &info);
    assert_int_equal(info.w, w);
    assert_int_equal(info.h, h);
    assert_int_equal(info.channels, ch);
    assert_memory_equal(info.pix, pix, (size_t)w * h * ch);
    if (stats) *stats = info.stats;
    png_info_free(&info);
    as_free(ctx, f, n);
    return n;
}

static unsigned char *read_file(const char *path, size_t *size) {
    FILE *fp = fopen(path, "rb");
    if (!fp) fail_msg("cannot open %s", path);
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    rewind(fp);
    assert_true(n > 0);
    unsigned char *buf = test_malloc((size_t)n);
    assert_int_equal(fread(buf, 1, (size_t)n, fp), (size_t)n);
    fclose(fp);
    *size = (size_t)n;
    return buf;
}

static void tmp_path(char *buf, size_t cap, const char *name) {
    snprintf(buf, cap, "/tmp/anistar_test_render_%ld_%s", (long)getpid(), name);
}

/* ==================================================================================== */
/* PNG tests                                                                            */
/* ==================================================================================== */

static void test_checksums(void **state) {
    (void)state;
    uint32_t table[256];
    as_crc32_table(table);
    /* The standard check value of CRC-32 and Adler-32's classic example. */
    const unsigned char *s = (const unsigned char *)"123456789";
    assert_int_equal(as_crc32_update(table, 0, s, 9), 0xCBF43926u);
    assert_int_equal(crc_bitwise(s, 9), 0xCBF43926u);
    assert_int_equal(as_adler32_update(1, (const unsigned char *)"Wikipedia", 9), 0x11E60398u);
    /* Random data in random pieces, including runs long enough to need the modulo. */
    tu_rng rng = {42};
    size_t n = 200000;
    unsigned char *d = test_malloc(n);
    for (size_t i = 0; i < n; i++) d[i] = (unsigned char)(i < 50000 ? 0xFF : tu_rng_u64(&rng));
    uint32_t c = 0, a = 1;
    for (size_t i = 0; i < n;) {
        size_t k = 1 + (size_t)(tu_rng_u64(&rng) % 9000);
        if (k > n - i) k = n - i;
        c = as_crc32_update(table, c, d + i, k);
        a = as_adler32_update(a, d + i, k);
        i += k;
    }
    assert_int_equal(c, crc_bitwise(d, n));
    assert_int_equal(a, adler_slow(d, n));
    test_free(d);
}

static void test_png_stored(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng rng = {7};
    /* 1x1, odd sizes, and rows longer than a stored block (16384 RGBA = 65536 bytes). */
    const uint32_t sizes[][3] = {{1, 1, 3}, {1, 1, 4}, {7, 5, 3}, {33, 17, 4},
                                 {16384, 2, 4}, {300, 400, 3}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        uint32_t w = sizes[k][0], h = sizes[k][1];
        int ch = (int)sizes[k][2];
        size_t n = (size_t)w * h * ch;
        unsigned char *pix = test_malloc(n);
        for (size_t i = 0; i < n; i++) pix[i] = (unsigned char)tu_rng_u64(&rng);
        inflate_stats st;
        size_t fsize = png_roundtrip(ctx, pix, w, h, ch, AS_PNG_STORED, &st);
        size_t raw = (size_t)h * (1 + (size_t)w * ch);
        assert_int_equal(st.fixed, 0);
        assert_int_equal(st.stored, (int)((raw + 65534) / 65535)); /* full blocks */
        /* signature + IHDR + zlib (2 + 5 per block + raw + 4) + IDATs + IEND */
        size_t idats = (raw + 6 + 5 * (size_t)st.stored + AS_PNG_IDAT_MAX - 1) / AS_PNG_IDAT_MAX;
        assert_int_equal(fsize, 8 + 25 + 2 + 5 * (size_t)st.stored + raw + 4 + 12 * idats + 12);
        test_free(pix);
    }
    anistar_context_free(ctx);
}

static void test_png_deflate(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng rng = {11};
    uint32_t w = 640, h = 480;
    size_t n = (size_t)w * h * 3;
    unsigned char *pix = test_malloc(n);
    /* (1) noise: incompressible, every block falls back to stored */
    for (size_t i = 0; i < n; i++) pix[i] = (unsigned char)tu_rng_u64(&rng);
    inflate_stats st;
    size_t noisy = png_roundtrip(ctx, pix, w, h, 3, AS_PNG_DEFLATE, &st);
    assert_true(st.stored > 0);
    assert_true(noisy <= 8 + 25 + 12 + n + h + 6 + 5 * (n / 16384 + 16) + 12 * (n / 65536 + 2));
    /* (2) flat areas, gradients and a few random specks: fixed-Huffman blocks, much smaller */
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            unsigned char *p = pix + 3 * ((size_t)y * w + x);
            int inside = (x - 320.0) * (x - 320.0) + (y - 240.0) * (y - 240.0) < 150.0 * 150.0;
            p[0] = inside ? (unsigned char)(x / 3) : 255;
            p[1] = inside ? (unsigned char)(y / 2) : 255;
            p[2] = inside ? 90 : 255;
            if (tu_rng_u64(&rng) % 97 == 0) p[1] = (unsigned char)tu_rng_u64(&rng);
        }
    size_t smooth = png_roundtrip(ctx, pix, w, h, 3, AS_PNG_DEFLATE, &st);
    assert_true(st.fixed > 0);
    size_t stored = png_roundtrip(ctx, pix, w, h, 3, AS_PNG_STORED, NULL);
    assert_true(smooth * 4 < stored);
    /* (3) RGBA, long runs (matches of 258 at distance 4) and tiny images */
    for (size_t i = 0; i < (size_t)w * h * 4 && i < n; i++) pix[i] = (unsigned char)(i % 4 * 50);
    png_roundtrip(ctx, pix, w, h / 2, 4, AS_PNG_DEFLATE, NULL);
    png_roundtrip(ctx, pix, 1, 1, 3, AS_PNG_DEFLATE, NULL);
    png_roundtrip(ctx, pix, 2, 3, 4, AS_PNG_DEFLATE, NULL);
    /* (4) mixtures: random length runs copied from random earlier places */
    for (size_t i = 0; i < n;) {
        size_t len = 1 + tu_rng_u64(&rng) % 300;
        if (len > n - i) len = n - i;
        if (i > 40000 && tu_rng_u64(&rng) % 3) {
            size_t d = 1 + tu_rng_u64(&rng) % 40000;
            for (size_t k = 0; k < len; k++) pix[i + k] = pix[i + k - d];
        } else {
            for (size_t k = 0; k < len; k++) pix[i + k] = (unsigned char)(tu_rng_u64(&rng) % 4);
        }
        i += len;
    }
    png_roundtrip(ctx, pix, w, h, 3, AS_PNG_DEFLATE, NULL);
    /* deterministic bytes */
    unsigned char *f1, *f2;
    size_t n1, n2;
    assert_int_equal(as_png_encode_mem(ctx, pix, w, h, 3, AS_PNG_DEFLATE, &f1, &n1), 0);
    assert_int_equal(as_png_encode_mem(ctx, pix, w, h, 3, AS_PNG_DEFLATE, &f2, &n2), 0);
    assert_int_equal(n1, n2);
    assert_memory_equal(f1, f2, n1);
    as_free(ctx, f1, n1);
    as_free(ctx, f2, n2);
    test_free(pix);
    anistar_context_free(ctx);
}

static void test_png_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    unsigned char px[12] = {0};
    unsigned char *f;
    size_t n;
    assert_int_equal(as_png_encode_mem(ctx, px, 0, 1, 3, AS_PNG_STORED, &f, &n), ANISTAR_EINVAL);
    assert_null(f);
    assert_int_equal(as_png_encode_mem(ctx, px, 1, 16385, 3, AS_PNG_STORED, &f, &n),
                     ANISTAR_EINVAL);
    assert_int_equal(as_png_encode_mem(ctx, px, 1, 1, 2, AS_PNG_STORED, &f, &n), ANISTAR_EINVAL);
    assert_int_equal(as_png_encode_mem(ctx, px, 1, 1, 3, (as_png_compression)9, &f, &n),
                     ANISTAR_EINVAL);
    assert_int_equal(as_png_encode_mem(ctx, NULL, 1, 1, 3, AS_PNG_STORED, &f, &n),
                     ANISTAR_EINVAL);
    /* unwritable paths */
    const char *bad[] = {"/nonexistent_dir_anistar/x.png", "/proc/anistar.png", "/tmp"};
    for (size_t i = 0; i < 3; i++) {
        assert_int_equal(as_png_write(ctx, bad[i], px, 2, 2, 3, AS_PNG_DEFLATE), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(ctx), bad[i]));
    }
    /* a full device (through a symbolic link to /dev/full): opening works, writing
     * fails; the link is removed, the device stays */
    struct stat sb;
    if (stat("/dev/full", &sb) == 0 && S_ISCHR(sb.st_mode)) {
        char link[256];
        tmp_path(link, sizeof link, "full.png");
        assert_int_equal(symlink("/dev/full", link), 0);
        assert_int_equal(as_png_write(ctx, link, px, 2, 2, 3, AS_PNG_STORED), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(ctx), "cannot write"));
        assert_int_equal(lstat(link, &sb), -1);
        assert_true(stat("/dev/full", &sb) == 0 && S_ISCHR(sb.st_mode));
    }
    /* a good file equals the in-memory encoding */
    char path[256];
    tmp_path(path, sizeof path, "ok.png");
    unsigned char img[5 * 4 * 3];
    for (size_t i = 0; i < sizeof img; i++) img[i] = (unsigned char)(i * 7);
    assert_int_equal(as_png_write(ctx, path, img, 5, 4, 3, AS_PNG_DEFLATE), ANISTAR_OK);
    size_t fn;
    unsigned char *fb = read_file(path, &fn);
    assert_int_equal(as_png_encode_mem(ctx, img, 5, 4, 3, AS_PNG_DEFLATE, &f, &n), ANISTAR_OK);
    assert_int_equal(fn, n);
    assert_memory_equal(fb, f, n);
    as_free(ctx, f, n);
    test_free(fb);
    remove(path);
    anistar_context_free(ctx);
}

static void test_png_alloc_failures(void **state) {
    (void)state;
    unsigned char img[64 * 64 * 3];
    for (size_t i = 0; i < sizeof img; i++) img[i] = (unsigned char)(i / 97);
    int ok = 0;
    for (long k = 0; k < 100 && !ok; k++) {
        tu_alloc ta;
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        if (!ctx) continue;
        unsigned char *f = NULL;
        size_t n = 0;
        anistar_status st = as_png_encode_mem(ctx, img, 64, 64, 3, AS_PNG_DEFLATE, &f, &n);
        if (st == ANISTAR_OK) {
            ok = 1;
            as_free(ctx, f, n);
        } else {
            assert_int_equal(st, ANISTAR_ENOMEM);
            assert_null(f);
        }
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
        assert_int_equal(ta.live_bytes, 0);
    }
    assert_true(ok);
    /* writing a file: out of memory leaves no file behind */
    char path[256];
    tmp_path(path, sizeof path, "nomem.png");
    tu_alloc ta;
    tu_alloc_init(&ta, 1); /* the context succeeds, the encoder's state fails */
    anistar_allocator al = tu_allocator(&ta);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    assert_int_equal(as_png_write(ctx, path, img, 64, 64, 3, AS_PNG_DEFLATE), ANISTAR_ENOMEM);
    assert_int_equal(access(path, F_OK), -1);
    anistar_context_free(ctx);
    assert_int_equal(ta.live_blocks, 0);
}

/* ==================================================================================== */
/* Rasterizer tests                                                                     */
/* ==================================================================================== */

static int is_bg(const unsigned char *px, const unsigned char bg[3]) {
    return px[0] == bg[0] && px[1] == bg[1] && px[2] == bg[2];
}

static const unsigned char *pixel(const unsigned char *rgb, uint32_t w, long x, long y) {
    return rgb + 3 * ((size_t)y * w + (size_t)x);
}

/* Render into a fresh buffer (test_malloc); asserts success. */
static unsigned char *render(anistar_context *ctx, const as_render_params *p, size_t nv,
                             const double *xyz, size_t nt, const int32_t *tri,
                             const double *values) {
    unsigned char *rgb = test_malloc((size_t)p->width * p->height * 3);
    anistar_status st = as_render(ctx, p, nv, xyz, nt, tri, values, rgb);
    if (st) fail_msg("as_render: %s", anistar_last_error(ctx));
    return rgb;
}

/* A square in the plane x = 0, [-1, 1] x [-0.5, 0.5] (y, z), facing +x. */
static const double SQ[] = {0, -1, -0.5, 0, 1, -0.5, 0, 1, 0.5, 0, -1, 0.5};
static const int32_t SQT[] = {0, 1, 2, 0, 2, 3};

static void test_render_fit(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 200;
    p.height = 150;
    p.azimuth = 0; /* look from +x: screen right = +y, up = +z */
    p.elevation = 0;
    p.edges = 0;
    for (int ss = 1; ss <= 4; ss++) {
        p.supersample = ss;
        unsigned char *rgb = render(ctx, &p, 4, SQ, 2, SQT, NULL);
        /* documented fit: margin m = floor(0.05 * 150) = 7; area 186 x 136; the 2 x 1
         * square scales by min(186/2, 136/1) = 93 -> 186 x 93 pixels centred at (100, 75) */
        double m = 7, aw = 200 - 2 * m, ah = 150 - 2 * m, s = fmin(aw / 2, ah / 1);
        double x0 = m + aw / 2 - s, x1 = m + aw / 2 + s, y0 = m + ah / 2 - s / 2,
               y1 = m + ah / 2 + s / 2;
        long bx0 = 1 << 30, bx1 = -1, by0 = 1 << 30, by1 = -1;
        for (long y = 0; y < 150; y++)
            for (long x = 0; x < 200; x++) {
                int inside = x + 1 <= x1 && x >= x0 && y + 1 <= y1 && y >= y0;
                const unsigned char *px = pixel(rgb, 200, x, y);
                if (inside && is_bg(px, p.background))
                    fail_msg("ss %d: pixel (%ld, %ld) inside the square is background", ss, x, y);
                if (!is_bg(px, p.background)) {
                    if (x < bx0) bx0 = x;
                    if (x > bx1) bx1 = x;
                    if (y < by0) by0 = y;
                    if (y > by1) by1 = y;
                }
            }
        /* coloured pixels are exactly those overlapping the square (border pixels hold
         * samples of it only when a sample centre falls inside) */
        assert_true(bx0 >= floor(x0) && bx0 <= ceil(x0));
        assert_true(bx1 >= floor(x1) - 1 && bx1 <= ceil(x1) - 1);
        assert_true(by0 >= floor(y0) && by0 <= ceil(y0));
        assert_true(by1 >= floor(y1) - 1 && by1 <= ceil(y1) - 1);
        /* a flat square facing the viewer is evenly shaded */
        assert_memory_equal(pixel(rgb, 200, 50, 60), pixel(rgb, 200, 150, 90), 3);
        test_free(rgb);
    }
    anistar_context_free(ctx);
}

/* Two triangles overlapping in projection, at x = 0 and x = 1 (nearer when looking from
 * +x), with different values. */
static void test_render_zbuffer(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double xyz[] = {0, -1, -1, 0, 1, -1, 0, 0, 1,    /* far, value 0 */
                          1, -1, 1,  1, 1, 1,  1, 0, -1}; /* near, value 1 (upside down) */
    const int32_t t1[] = {0, 1, 2, 3, 5, 4}, t2[] = {3, 5, 4, 0, 1, 2};
    const double v1[] = {0, 1}, v2[] = {1, 0};
    as_render_params p;
    as_render_params_init(&p);
    p.width = 120;
    p.height = 120;
    p.azimuth = 0;
    p.elevation = 0;
    p.edges = 0;
    p.legend = 0;
    p.ambient = 1; /* unshaded: pixels are the colormap */
    p.diffuse = 0;
    p.supersample = 1;
    unsigned char *a = render(ctx, &p, 6, xyz, 2, t1, v1);
    unsigned char *b = render(ctx, &p, 6, xyz, 2, t2, v2);
    assert_memory_equal(a, b, 120 * 120 * 3); /* independent of the drawing order */
    double c0[3], c1[3];
    as_render_colormap(0, c0);
    as_render_colormap(1, c1);
    /* the centre is covered by both: the near one (value 1) shows */
    const unsigned char *px = pixel(a, 120, 60, 60);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * c1[k] + 0.5));
    /* near the top centre only the far triangle's apex region... and the near one's base:
     * the near triangle's base is at z = +1 (top), the far one's at z = -1 (bottom).
     * Bottom corners belong to the far triangle only. */
    px = pixel(a, 120, 12, 106);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * c0[k] + 0.5));
    px = pixel(a, 120, 12, 13);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * c1[k] + 0.5));
    test_free(a);
    test_free(b);
    anistar_context_free(ctx);
}

/* Strips of triangles with values 0, 0.1, ..., 1 drawn unshaded match the colormap; the
 * colormap's luminance increases (perceptual order). */
static void test_render_colormap(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    enum { N = 11 };
    double xyz[(N + 1) * 2 * 3];
    int32_t tri[N * 2 * 3];
    double val[N * 2];
    for (int i = 0; i <= N; i++) {
        double y = i;
        double *a = xyz + 6 * i;
        a[0] = 0, a[1] = y, a[2] = 0;
        a[3] = 0, a[4] = y, a[5] = 4;
    }
    for (int i = 0; i < N; i++) {
        int32_t *t = tri + 6 * i;
        t[0] = 2 * i, t[1] = 2 * i + 2, t[2] = 2 * i + 3;
        t[3] = 2 * i, t[4] = 2 * i + 3, t[5] = 2 * i + 1;
        val[2 * i] = val[2 * i + 1] = i / 10.0;
    }
    as_render_params p;
    as_render_params_init(&p);
    p.width = 440;
    p.height = 200;
    p.azimuth = 0;
    p.elevation = 0;
    p.edges = 0;
    p.legend = 0;
    p.ambient = 1;
    p.diffuse = 0;
    p.vmin = 0;
    p.vmax = 1;
    unsigned char *rgb = render(ctx, &p, (N + 1) * 2, xyz, N * 2, tri, val);
    /* fit: m = 10, area 420 x 180, strip 11 x 4 -> scale min(420/11, 45) = 38.18 */
    double s = 420.0 / 11, x0 = 10 + 210 - 5.5 * s;
    double prev_lum = -1;
    for (int i = 0; i < N; i++) {
        long x = (long)floor(x0 + (i + 0.5) * s);
        const unsigned char *px = pixel(rgb, 440, x, 100);
        double c[3];
        as_render_colormap(i / 10.0, c);
        for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * c[k] + 0.5));
        double lum = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        assert_true(lum > prev_lum);
        prev_lum = lum;
    }
    /* the colormap's luminance is monotone on a fine grid too, and NaN is grey */
    prev_lum = -1;
    for (int i = 0; i <= 1000; i++) {
        double c[3];
        as_render_colormap(i / 1000.0, c);
        double lum = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        assert_true(lum >= prev_lum);
        prev_lum = lum;
    }
    double g[3];
    as_render_colormap(NAN, g);
    assert_true(g[0] == g[1] && g[1] == g[2]);
    test_free(rgb);
    anistar_context_free(ctx);
}

/* Shading: a face at angle to the view is darker than one facing the documented light
 * more; the ratio pixel / colour is ambient + diffuse * max(0, n.l). Back faces are
 * tinted differently from front faces. */
static void test_render_shading(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 200;
    p.height = 150;
    p.azimuth = 0;
    p.elevation = 0;
    p.edges = 0;
    p.legend = 0;
    p.supersample = 1;
    p.vmin = 0;
    p.vmax = 1;
    const double val[2] = {1, 1}; /* yellow: every channel well above 0 */
    unsigned char *rgb = render(ctx, &p, 4, SQ, 2, SQT, val);
    /* normal (1,0,0) = the view direction; light (-0.35, 0.45, 1)/|.| in (right, up, view) */
    double ndl = 1 / sqrt(0.35 * 0.35 + 0.45 * 0.45 + 1);
    double c[3];
    as_render_colormap(1, c);
    const unsigned char *px = pixel(rgb, 200, 100, 75);
    for (int k = 0; k < 3; k++) /* within 1 level: the renderer keeps colours as floats */
        assert_true(fabs(px[k] - 255 * c[k] * (p.ambient + p.diffuse * ndl)) <= 1);
    /* the same square reversed (back face) has another colour */
    const int32_t rev[] = {0, 2, 1, 0, 3, 2};
    unsigned char *back = render(ctx, &p, 4, SQ, 2, rev, val);
    const unsigned char *q = pixel(back, 200, 100, 75);
    assert_true(abs(q[0] - px[0]) + abs(q[1] - px[1]) + abs(q[2] - px[2]) > 60);
    /* a square turned away from the light (normal toward -right... here: tilted about z
     * so that its normal leans to +right, away from the light's -right component) is
     * darker */
    const double tilted[] = {0.5, -1, -0.5, -0.5, 1, -0.5, -0.5, 1, 0.5, 0.5, -1, 0.5};
    unsigned char *dark = render(ctx, &p, 4, tilted, 2, SQT, val);
    const unsigned char *d = pixel(dark, 200, 100, 75);
    assert_true(d[1] < px[1]);
    test_free(rgb);
    test_free(back);
    test_free(dark);
    anistar_context_free(ctx);
}

/* Edges: drawn along visible edges only, never through a front face over a hidden edge,
 * and faded away on triangles thinner than 1.5 pixels. */
static void test_render_edges(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 200;
    p.height = 150;
    p.azimuth = 0;
    p.elevation = 0;
    p.legend = 0;
    unsigned char *on = render(ctx, &p, 4, SQ, 2, SQT, NULL);
    p.edges = 0;
    unsigned char *off = render(ctx, &p, 4, SQ, 2, SQT, NULL);
    /* the diagonal from (y,z) = (-1,-0.5) to (1,0.5): its midpoint is the image centre */
    assert_memory_not_equal(pixel(on, 200, 100, 75), pixel(off, 200, 100, 75), 3);
    assert_memory_equal(pixel(on, 200, 60, 50), pixel(off, 200, 60, 50), 3);
    test_free(on);
    test_free(off);

    /* hidden edges: a big front square (x = 1) in front of a small back one (x = 0):
     * with and without the back one, the picture is the same */
    const double two[] = {1, -1, -0.5, 1, 1, -0.5, 1, 1, 0.5, 1, -1, 0.5,
                          0, -0.5, -0.25, 0, 0.5, -0.25, 0, 0.5, 0.25, 0, -0.5, 0.25};
    const int32_t tt[] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
    p.edges = 1;
    unsigned char *a = render(ctx, &p, 8, two, 4, tt, NULL);
    unsigned char *b = render(ctx, &p, 8, two, 2, tt, NULL);
    assert_memory_equal(a, b, 200 * 150 * 3);
    test_free(a);
    test_free(b);

    /* a fine grid (cells of ~1 pixel): edges faded out, same picture as without edges */
    enum { G = 60 };
    double *g = test_malloc((G + 1) * (G + 1) * 3 * sizeof(double));
    int32_t *gt = test_malloc(G * G * 6 * sizeof(int32_t));
    for (int i = 0; i <= G; i++)
        for (int j = 0; j <= G; j++) {
            double *v = g + 3 * (i * (G + 1) + j);
            v[0] = 0, v[1] = j, v[2] = i;
        }
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            int32_t a0 = i * (G + 1) + j, a1 = a0 + 1, a2 = a0 + G + 1, a3 = a2 + 1;
            int32_t *t = gt + 6 * (i * G + j);
            t[0] = a0, t[1] = a1, t[2] = a3, t[3] = a0, t[4] = a3, t[5] = a2;
        }
    p.width = 80;
    p.height = 80; /* 72 px for 60 cells */
    unsigned char *e1 = render(ctx, &p, (G + 1) * (G + 1), g, G * G * 2, gt, NULL);
    p.edges = 0;
    unsigned char *e0 = render(ctx, &p, (G + 1) * (G + 1), g, G * G * 2, gt, NULL);
    assert_memory_equal(e1, e0, 80 * 80 * 3);
    test_free(e1);
    test_free(e0);
    test_free(g);
    test_free(gt);
    anistar_context_free(ctx);
}

/* Hostile input: empty mesh, degenerate triangles, NaN values, equal values, bad params. */
static void test_render_hostile(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 64;
    p.height = 48;
    unsigned char *rgb = test_malloc(64 * 48 * 3);
    /* empty */
    assert_int_equal(as_render(ctx, &p, 0, NULL, 0, NULL, NULL, rgb), ANISTAR_OK);
    for (size_t i = 0; i < 64 * 48; i++) assert_true(is_bg(rgb + 3 * i, p.background));
    /* one degenerate triangle (collinear), one with a repeated vertex, and a point */
    const double deg[] = {0, 0, 0, 1, 1, 1, 2, 2, 2};
    const int32_t dt[] = {0, 1, 2, 0, 0, 1, 1, 1, 1};
    double dv[3] = {1, 2, 3};
    for (int k = 0; k < 4; k++) { /* each alone, then all three */
        assert_int_equal(as_render(ctx, &p, 3, deg, k < 3 ? 1 : 3, dt + 3 * (k % 3), dv, rgb), 0);
        for (size_t i = 0; i < 64 * 48; i++) assert_true(is_bg(rgb + 3 * i, p.background));
    }
    /* NaN values: grey, the other ones coloured over the finite range */
    p.width = 200;
    p.height = 150;
    p.azimuth = 0;
    p.elevation = 0;
    p.edges = 0;
    p.legend = 0;
    p.ambient = 1;
    p.diffuse = 0;
    unsigned char *img = test_malloc(200 * 150 * 3);
    const double nanv[2] = {NAN, 5};
    assert_int_equal(as_render(ctx, &p, 4, SQ, 2, SQT, nanv, img), 0);
    /* triangle 0 = (0,1,2): lower right half in the image (y right, z up) */
    double grey[3], top[3], mid[3];
    as_render_colormap(NAN, grey);
    as_render_colormap(0.5, mid);
    const unsigned char *px = pixel(img, 200, 100, 100);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * grey[k] + 0.5));
    px = pixel(img, 200, 40, 50);
    /* a single finite value: vmin == vmax, drawn at the middle of the colormap */
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * mid[k] + 0.5));
    /* all values equal, infinities at the ends */
    const double eq[2] = {3, 3}, inf[2] = {INFINITY, -INFINITY};
    assert_int_equal(as_render(ctx, &p, 4, SQ, 2, SQT, eq, img), 0);
    px = pixel(img, 200, 100, 100);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * mid[k] + 0.5));
    assert_int_equal(as_render(ctx, &p, 4, SQ, 2, SQT, inf, img), 0);
    as_render_colormap(1, top);
    px = pixel(img, 200, 100, 100);
    for (int k = 0; k < 3; k++) assert_int_equal(px[k], (int)floor(255 * top[k] + 0.5));
    /* bad parameters and meshes */
    as_render_params q = p;
    q.width = 16385;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "16385"));
    q = p;
    q.height = 0;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    q = p;
    q.supersample = 5;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    q = p;
    q.azimuth = NAN;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    q = p;
    q.vmin = 2;
    q.vmax = 1;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    q = p;
    q.vmin = 2; /* vmax NaN */
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    q = p;
    q.up = 3;
    assert_int_equal(as_render(ctx, &q, 4, SQ, 2, SQT, NULL, img), ANISTAR_EINVAL);
    const int32_t badt[] = {0, 1, 4};
    assert_int_equal(as_render(ctx, &p, 4, SQ, 1, badt, NULL, img), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "out of range"));
    double nanxyz[12];
    memcpy(nanxyz, SQ, sizeof nanxyz);
    nanxyz[4] = NAN;
    assert_int_equal(as_render(ctx, &p, 4, nanxyz, 2, SQT, NULL, img), ANISTAR_EINVAL);
    assert_int_equal(as_render(ctx, &p, 4, NULL, 2, SQT, NULL, img), ANISTAR_EINVAL);
    /* coordinates whose projection overflows: refused; scaled by 2^+-900 (exact): the
     * same picture as the original (the fit is scale invariant) */
    double big[12];
    memcpy(big, SQ, sizeof big);
    big[4] = 1.7e308;
    big[1] = -1.7e308;
    assert_int_equal(as_render(ctx, &p, 4, big, 2, SQT, NULL, img), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "overflow"));
    p.azimuth = 25;
    p.elevation = 35;
    assert_int_equal(as_render(ctx, &p, 4, SQ, 2, SQT, NULL, img), 0);
    unsigned char *img2 = test_malloc(200 * 150 * 3);
    for (int e = -900; e <= 900; e += 1800) {
        for (int i = 0; i < 12; i++) big[i] = ldexp(SQ[i], e);
        assert_int_equal(as_render(ctx, &p, 4, big, 2, SQT, NULL, img2), 0);
        assert_memory_equal(img, img2, 200 * 150 * 3);
    }
    test_free(img2);
    test_free(img);
    test_free(rgb);
    anistar_context_free(ctx);
}

/* A real mesh: knot1 rendered twice gives the same bytes; the PNG decodes to the
 * framebuffer; the legend is drawn (a colour bar from the bottom to the top colour)
 * outside the mesh; up axes and views give distinct pictures. */
static void test_render_knot(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh m;
    as_trimesh_init(&m);
    assert_int_equal(as_mesh_read(ctx, KNOT, &m), ANISTAR_OK);
    double *val = test_malloc(m.nt * sizeof(double));
    assert_int_equal(anistar_triangle_values(ctx, ANISTAR_COLOR_QUALITY, m.nv, m.xyz, m.nt,
                                             m.tri, NULL, val),
                     ANISTAR_OK);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 480;
    p.height = 360;
    p.label = "radius-edge ratio";
    unsigned char *a = render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val);
    unsigned char *b = render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val);
    assert_memory_equal(a, b, 480 * 360 * 3);
    png_roundtrip(ctx, a, 480, 360, 3, AS_PNG_DEFLATE, NULL);
    /* legend: in the right third, pixels of the top and bottom colours of the bar and
     * dark text pixels; without the legend that area is background */
    double lo[3], hi[3];
    as_render_colormap(0.005, lo);
    as_render_colormap(0.995, hi);
    int found_lo = 0, found_hi = 0, found_text = 0;
    for (long y = 0; y < 360; y++)
        for (long x = 320; x < 480; x++) {
            const unsigned char *px = pixel(a, 480, x, y);
            int dl = 0, dh = 0;
            for (int k = 0; k < 3; k++) {
                dl += abs(px[k] - (int)(255 * lo[k] + 0.5));
                dh += abs(px[k] - (int)(255 * hi[k] + 0.5));
            }
            found_lo |= dl <= 6;
            found_hi |= dh <= 6;
            found_text |= px[0] == 30 && px[1] == 30 && px[2] == 30;
        }
    assert_true(found_lo && found_hi && found_text);
    p.legend = 0;
    unsigned char *c = render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val);
    assert_memory_not_equal(a, c, 480 * 360 * 3);
    for (long y = 0; y < 360; y++)
        for (long x = 466; x < 480; x++) assert_true(is_bg(pixel(c, 480, x, y), p.background));
    p.up = 1;
    unsigned char *d = render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val);
    assert_memory_not_equal(c, d, 480 * 360 * 3);
    test_free(a);
    test_free(b);
    test_free(c);
    test_free(d);
    test_free(val);
    as_trimesh_free(ctx, &m);
    anistar_context_free(ctx);
}

/* ==================================================================================== */
/* Public API                                                                           */
/* ==================================================================================== */

static void test_triangle_values(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double s3 = sqrt(3.0);
    /* equilateral, right isosceles, collinear */
    const double xyz[] = {0, 0, 0, 1, 0, 0, 0.5, s3 / 2, 0, 0, 1, 0, 2, 0, 0};
    const int32_t tri[] = {0, 1, 2, 0, 1, 3, 0, 1, 4};
    double q[3], a[3];
    assert_int_equal(anistar_triangle_values(ctx, ANISTAR_COLOR_QUALITY, 5, xyz, 3, tri, NULL, q),
                     0);
    assert_true(fabs(q[0] - 1 / s3) < 1e-15);
    assert_true(fabs(q[1] - sqrt(0.5)) < 1e-15); /* R = hypotenuse / 2, shortest = 1 */
    assert_true(isinf(q[2]) && q[2] > 0);
    assert_int_equal(
        anistar_triangle_values(ctx, ANISTAR_COLOR_ANISOTROPY, 5, xyz, 3, tri, NULL, a), 0);
    assert_true(fabs(a[0] - 2 / s3) < 1e-15);
    assert_true(fabs(a[1] - 2) < 1e-15); /* sqrt 2 / (altitude sqrt(2)/2) */
    assert_true(isinf(a[2]));
    /* the measures are invariant under similarity transforms */
    tu_rng rng = {3};
    for (int it = 0; it < 200; it++) {
        double p[9], r[9];
        for (int i = 0; i < 9; i++) p[i] = tu_rng_range(&rng, -1, 1);
        double s = tu_rng_range(&rng, 0.01, 100), th = tu_rng_range(&rng, 0, 6.28);
        for (int v = 0; v < 3; v++) {
            const double *x = p + 3 * v;
            r[3 * v] = s * (cos(th) * x[0] - sin(th) * x[1]) + 5;
            r[3 * v + 1] = s * (sin(th) * x[0] + cos(th) * x[1]) - 2;
            r[3 * v + 2] = s * x[2] + 1;
        }
        double q0 = as_tri_radius_edge(p, p + 3, p + 6), q1 = as_tri_radius_edge(r, r + 3, r + 6);
        double a0 = as_tri_aspect(p, p + 3, p + 6), a1 = as_tri_aspect(r, r + 3, r + 6);
        assert_true(fabs(q0 - q1) <= 1e-9 * q0);
        assert_true(fabs(a0 - a1) <= 1e-9 * a0);
        assert_true(q0 >= 1 / s3 * (1 - 1e-12));
        assert_true(a0 >= 2 / s3 * (1 - 1e-12));
    }
    /* tensors: per-vertex sqrt(lmax / lmin), max over the triangle; not SPD -> NaN */
    double tens[5 * 6] = {1, 0, 0, 1, 0, 1, /* isotropic: 1 */
                          4, 0, 0, 1, 0, 1, /* 2 */
                          1, 0, 0, 1, 0, 9, /* 3 */
                          1, 0, 0, 1, 0, 1,
                          1, 0, 0, -1, 0, 1}; /* indefinite */
    assert_int_equal(
        anistar_triangle_values(ctx, ANISTAR_COLOR_ANISOTROPY, 5, xyz, 3, tri, tens, a), 0);
    assert_true(fabs(a[0] - 3) < 1e-12);
    assert_true(fabs(a[1] - 2) < 1e-12);
    assert_true(isnan(a[2]));
    /* a rotated tensor gives the same ratio */
    double rot[6] = {2.5, 1.5, 0, 2.5, 0, 1}; /* eigenvalues 4, 1, 1 */
    memcpy(tens + 6, rot, sizeof rot);
    assert_int_equal(
        anistar_triangle_values(ctx, ANISTAR_COLOR_ANISOTROPY, 5, xyz, 3, tri, tens, a), 0);
    assert_true(fabs(a[1] - 2) < 1e-12);
    /* errors */
    assert_int_equal(anistar_triangle_values(ctx, ANISTAR_COLOR_NONE, 5, xyz, 3, tri, NULL, q),
                     ANISTAR_EINVAL);
    const int32_t bad[] = {0, 1, 5};
    assert_int_equal(
        anistar_triangle_values(ctx, ANISTAR_COLOR_QUALITY, 5, xyz, 1, bad, NULL, q),
        ANISTAR_EINVAL);
    anistar_context_free(ctx);
}

static void test_render_api(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    char path[256];
    tmp_path(path, sizeof path, "knot.png");
    anistar_render_options opt;
    anistar_render_options_init(&opt);
    assert_int_equal(opt.width, 1024);
    assert_int_equal(opt.height, 768);
    opt.width = 320;
    opt.height = 240;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &opt), ANISTAR_OK);
    size_t n;
    unsigned char *f = read_file(path, &n);
    png_info info;
    png_decode(f, n, &info);
    assert_int_equal(info.w, 320);
    assert_int_equal(info.h, 240);
    assert_true(info.stats.fixed > 0);
    /* the same picture as the internal renderer with the same values and parameters */
    as_trimesh m;
    as_trimesh_init(&m);
    assert_int_equal(as_mesh_read(ctx, KNOT, &m), 0);
    double *val = test_malloc(m.nt * sizeof(double));
    assert_int_equal(anistar_triangle_values(ctx, ANISTAR_COLOR_QUALITY, m.nv, m.xyz, m.nt,
                                             m.tri, NULL, val),
                     0);
    as_render_params p;
    as_render_params_init(&p);
    p.width = 320;
    p.height = 240;
    p.label = "radius-edge ratio";
    unsigned char *rgb = render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val);
    assert_memory_equal(rgb, info.pix, 320 * 240 * 3);
    png_info_free(&info);
    test_free(f);
    /* stored, arrays, values given */
    opt.compress = 0;
    assert_int_equal(anistar_render_arrays(ctx, m.nv, m.xyz, m.nt, m.tri, NULL, val,
                                           "radius-edge ratio", path, &opt),
                     ANISTAR_OK);
    f = read_file(path, &n);
    png_decode(f, n, &info);
    assert_int_equal(info.stats.fixed, 0);
    assert_memory_equal(rgb, info.pix, 320 * 240 * 3);
    png_info_free(&info);
    test_free(f);
    /* none, anisotropy, an empty mesh */
    opt.compress = 1;
    opt.color = ANISTAR_COLOR_NONE;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &opt), ANISTAR_OK);
    opt.color = ANISTAR_COLOR_ANISOTROPY;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &opt), ANISTAR_OK);
    assert_int_equal(anistar_render_arrays(ctx, 0, NULL, 0, NULL, NULL, NULL, NULL, path, &opt),
                     ANISTAR_OK);
    f = read_file(path, &n);
    png_decode(f, n, &info);
    for (size_t i = 0; i < 320 * 240 * 3; i++) assert_int_equal(info.pix[i], 255);
    png_info_free(&info);
    test_free(f);
    /* a .sol whose vertex count does not match, then a matching one */
    char sol[256];
    tmp_path(sol, sizeof sol, "t.sol");
    FILE *fp = fopen(sol, "w");
    assert_non_null(fp);
    fprintf(fp, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n2\n1 3\n"
                "1 0 1 0 0 1\n1 0 1 0 0 1\nEnd\n");
    fclose(fp);
    opt.sol_path = sol;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &opt), ANISTAR_EFORMAT);
    fp = fopen(sol, "w");
    assert_non_null(fp);
    fprintf(fp, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n%zu\n1 3\n", m.nv);
    for (size_t i = 0; i < m.nv; i++) fprintf(fp, "%d 0 1 0 0 1\n", i % 2 ? 4 : 1);
    fprintf(fp, "End\n");
    fclose(fp);
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &opt), ANISTAR_OK);
    remove(sol);
    opt.sol_path = NULL;
    /* tensors carried by a PLY: the file renders as the arrays with those tensors, and
     * differently from the same mesh without tensors (aspect ratio) */
    {
        double *tens = test_malloc(6 * m.nv * sizeof(double));
        for (size_t i = 0; i < m.nv; i++) {
            double e = 1 + 3 * fabs(m.xyz[3 * i]); /* anisotropy grows with |x| */
            double t6[6] = {e * e, 0, 0, 1, 0, 1};
            memcpy(tens + 6 * i, t6, sizeof t6);
        }
        char ply[256];
        tmp_path(ply, sizeof ply, "t.ply");
        as_trimesh mt;
        as_trimesh_init(&mt);
        assert_int_equal(as_trimesh_set(ctx, &mt, m.nv, m.xyz, m.nt, m.tri, tens), 0);
        assert_int_equal(as_mesh_write(ctx, ply, &mt, NULL, 0), 0);
        as_trimesh_free(ctx, &mt);
        char p2[256];
        tmp_path(p2, sizeof p2, "arrays.png");
        assert_int_equal(anistar_render_file(ctx, ply, path, &opt), ANISTAR_OK);
        assert_int_equal(anistar_render_arrays(ctx, m.nv, m.xyz, m.nt, m.tri, tens, NULL, NULL,
                                               p2, &opt),
                         ANISTAR_OK);
        size_t n1, n2;
        unsigned char *f1 = read_file(path, &n1), *f2 = read_file(p2, &n2);
        assert_int_equal(n1, n2);
        assert_memory_equal(f1, f2, n1);
        test_free(f2);
        assert_int_equal(anistar_render_arrays(ctx, m.nv, m.xyz, m.nt, m.tri, NULL, NULL, NULL,
                                               p2, &opt),
                         ANISTAR_OK);
        f2 = read_file(p2, &n2);
        assert_true(n1 != n2 || memcmp(f1, f2, n1) != 0);
        test_free(f1);
        test_free(f2);
        test_free(tens);
        remove(ply);
        remove(p2);
    }
    /* errors: bad options, unreadable mesh, unwritable output, bad arrays */
    anistar_render_options bad = opt;
    bad.width = 20000;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &bad), ANISTAR_EINVAL);
    bad = opt;
    bad.supersample = 0;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &bad), ANISTAR_EINVAL);
    bad = opt;
    bad.color = (anistar_color_by)7;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &bad), ANISTAR_EINVAL);
    bad = opt;
    bad.range_min = 1;
    bad.range_max = 1;
    assert_int_equal(anistar_render_file(ctx, KNOT, path, &bad), ANISTAR_EINVAL);
    assert_int_equal(anistar_render_file(ctx, "/nonexistent/knot.off", path, &opt), ANISTAR_EIO);
    assert_non_null(strstr(anistar_last_error(ctx), "/nonexistent/knot.off"));
    assert_int_equal(anistar_render_file(ctx, KNOT, "/nonexistent_dir/x.png", &opt),
                     ANISTAR_EIO);
    assert_non_null(strstr(anistar_last_error(ctx), "/nonexistent_dir/x.png"));
    const int32_t bt[] = {0, 1, 9};
    assert_int_equal(anistar_render_arrays(ctx, 3, m.xyz, 1, bt, NULL, NULL, NULL, path, &opt),
                     ANISTAR_EINVAL);
    assert_int_equal(anistar_render_file(ctx, NULL, path, &opt), ANISTAR_EINVAL);
    assert_int_equal(anistar_render_file(NULL, KNOT, path, &opt), ANISTAR_EINVAL);
    test_free(rgb);
    test_free(val);
    as_trimesh_free(ctx, &m);
    remove(path);
    anistar_context_free(ctx);
}

static void test_render_alloc_failures(void **state) {
    (void)state;
    char path[256];
    tmp_path(path, sizeof path, "alloc.png");
    const double xyz[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    const int32_t tri[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    anistar_render_options opt;
    anistar_render_options_init(&opt);
    opt.width = 120;
    opt.height = 90;
    int ok = 0;
    for (long k = 0; k < 200 && !ok; k++) {
        tu_alloc ta;
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        if (!ctx) continue;
        anistar_status st =
            anistar_render_arrays(ctx, 4, xyz, 4, tri, NULL, NULL, NULL, path, &opt);
        if (st == ANISTAR_OK) ok = 1;
        else assert_int_equal(st, ANISTAR_ENOMEM);
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
        assert_int_equal(ta.live_bytes, 0);
    }
    assert_true(ok);
    remove(path);
}

/* ==================================================================================== */
/* The command-line tool                                                                */
/* ==================================================================================== */

typedef struct run_result {
    int status;
    char err[4096];
    size_t out_len;
} run_result;

static void run_tool(const char *const *args, run_result *res) {
    char outname[] = "/tmp/anistar_render_out_XXXXXX", errname[] = "/tmp/anistar_render_err_XXXXXX";
    int fo = mkstemp(outname), fe = mkstemp(errname);
    assert_true(fo >= 0 && fe >= 0);
    const char *argv[32];
    int n = 0;
    argv[n++] = TOOL;
    for (int i = 0; args[i] && n < 31; i++) argv[n++] = args[i];
    argv[n] = NULL;
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        dup2(fo, 1);
        dup2(fe, 2);
        execv(TOOL, (char *const *)argv);
        _exit(127);
    }
    int wst = 0;
    assert_true(waitpid(pid, &wst, 0) == pid);
    res->status = WIFEXITED(wst) ? WEXITSTATUS(wst) : -1;
    res->out_len = (size_t)lseek(fo, 0, SEEK_END);
    lseek(fe, 0, SEEK_SET);
    ssize_t r = read(fe, res->err, sizeof res->err - 1);
    res->err[r > 0 ? r : 0] = '\0';
    close(fo);
    close(fe);
    unlink(outname);
    unlink(errname);
}

static void assert_one_line(const run_result *r) {
    size_t len = strlen(r->err);
    if (!(len > 10 && r->err[len - 1] == '\n' && strchr(r->err, '\n') == r->err + len - 1 &&
          !strncmp(r->err, "anistar: ", 9)))
        fail_msg("stderr is not one 'anistar: ...' line: '%s'", r->err);
}

static void test_cli(void **state) {
    (void)state;
    char out[256];
    tmp_path(out, sizeof out, "cli.png");
    run_result *r = test_malloc(sizeof *r);
    const char *ok[] = {"render", KNOT, "-o", out, "--color", "quality", "--view", "30,20", NULL};
    run_tool(ok, r);
    if (r->status != 0) fail_msg("exit %d: %s", r->status, r->err);
    assert_int_equal(r->out_len, 0);
    assert_string_equal(r->err, "");
    size_t n;
    unsigned char *f = read_file(out, &n);
    png_info info;
    png_decode(f, n, &info);
    assert_int_equal(info.w, 1024);
    assert_int_equal(info.h, 768);
    png_info_free(&info);
    test_free(f);
    const char *opts[] = {"render", "-o", out, KNOT, "--size", "200x100", "--edges", "off",
                          "--color", "anisotropy", "--up", "y", "--range", "1,2", NULL};
    run_tool(opts, r);
    if (r->status != 0) fail_msg("exit %d: %s", r->status, r->err);
    f = read_file(out, &n);
    png_decode(f, n, &info);
    assert_int_equal(info.w, 200);
    assert_int_equal(info.h, 100);
    png_info_free(&info);
    test_free(f);
    remove(out);

    /* usage errors: exit 2, one line, no output file */
    const char *usage[][12] = {
        {"render", KNOT, NULL},
        {"render", "-o", out, NULL},
        {"render", KNOT, "-o", out, "--view", "30", NULL},
        {"render", KNOT, "-o", out, "--view", "a,b", NULL},
        {"render", KNOT, "-o", out, "--color", "pink", NULL},
        {"render", KNOT, "-o", out, "--size", "20000x10", NULL},
        {"render", KNOT, "-o", out, "--size", "0x10", NULL},
        {"render", KNOT, "-o", out, "--size", "12", NULL},
        {"render", KNOT, "-o", out, "--edges", "maybe", NULL},
        {"render", KNOT, "-o", out, "--frobnicate", NULL},
        {"render", KNOT, "-o", out, "-o", out, NULL},
        {"render", KNOT, "-o", "/tmp/x.jpg", NULL},
        {"render", KNOT, KNOT, "-o", out, NULL},
        {"render", KNOT, "-o", out, "--range", "2,1", NULL},
        {"render", KNOT, "-o", out, "--up", "w", NULL},
        {"render", KNOT, "-o", out, "--color", "quality", "--sol", "x.sol", NULL},
        {"render", KNOT, "-o", NULL},
    };
    for (size_t i = 0; i < sizeof usage / sizeof usage[0]; i++) {
        run_tool(usage[i], r);
        if (r->status != 2) fail_msg("usage case %zu: exit %d, '%s'", i, r->status, r->err);
        assert_one_line(r);
        assert_int_equal(access(out, F_OK), -1);
    }
    /* runtime errors: exit 1, one line */
    const char *runtime[][8] = {
        {"render", "/nonexistent/mesh.off", "-o", out, NULL},
        {"render", KNOT, "-o", "/nonexistent_dir/x.png", NULL},
        {"render", AS_TEST_DATA_DIR "/README.md", "-o", out, NULL},
    };
    const char *msgs[] = {"/nonexistent/mesh.off", "/nonexistent_dir/x.png", "README.md"};
    for (size_t i = 0; i < sizeof runtime / sizeof runtime[0]; i++) {
        run_tool(runtime[i], r);
        if (r->status != 1) fail_msg("runtime case %zu: exit %d, '%s'", i, r->status, r->err);
        assert_one_line(r);
        if (!strstr(r->err, msgs[i])) fail_msg("case %zu: '%s' lacks '%s'", i, r->err, msgs[i]);
    }
    test_free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_checksums),
        cmocka_unit_test(test_png_stored),
        cmocka_unit_test(test_png_deflate),
        cmocka_unit_test(test_png_errors),
        cmocka_unit_test(test_png_alloc_failures),
        cmocka_unit_test(test_render_fit),
        cmocka_unit_test(test_render_zbuffer),
        cmocka_unit_test(test_render_colormap),
        cmocka_unit_test(test_render_shading),
        cmocka_unit_test(test_render_edges),
        cmocka_unit_test(test_render_hostile),
        cmocka_unit_test(test_render_knot),
        cmocka_unit_test(test_triangle_values),
        cmocka_unit_test(test_render_api),
        cmocka_unit_test(test_render_alloc_failures),
        cmocka_unit_test(test_cli),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
