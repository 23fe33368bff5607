/*
 * png.c — the PNG encoder of png.h: chunks, the zlib wrapper, and a small deflate
 * compressor (stored blocks, or fixed-Huffman blocks fed by greedy LZ77 matching).
 *
 * Format facts used here (PNG specification, RFC 1950 zlib, RFC 1951 deflate):
 *  - chunk = length (4 bytes, big endian) | type (4) | data | CRC-32 of type and data;
 *  - zlib = CMF FLG (CMF*256 + FLG divisible by 31) | deflate blocks | Adler-32;
 *  - deflate bits are packed from the least significant bit of each byte; Huffman codes
 *    are sent from their most significant bit, so they are bit-reversed before packing;
 *  - the fixed literal/length code: symbols 0-143 have 8 bits (codes 0x30..), 144-255
 *    9 bits (0x190..), 256-279 7 bits (0..), 280-287 8 bits (0xC0..); distance codes
 *    are 5-bit integers; lengths 3..258 and distances 1..32768 are a code plus extra
 *    bits (tables below).
 */
#include "io/png.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

enum {
    WSIZE = 32768,                   /* the LZ77 window (deflate's maximum distance) */
    WMASK = WSIZE - 1,
    WIN = 2 * WSIZE,                 /* the buffer: history + lookahead, slid by WSIZE */
    MIN_MATCH = 3,
    MAX_MATCH = 258,
    MIN_LOOKAHEAD = MAX_MATCH + MIN_MATCH + 1,
    MAX_DIST = WSIZE - MIN_LOOKAHEAD, /* farthest match: its source survives a slide */
    HBITS = 15,
    HSIZE = 1 << HBITS,
    MAX_CHAIN = 48,                  /* candidates tried per position (speed/size) */
    BLOCK_BYTES = 16384,             /* a block closes after this much input */
    BLOCK_TOKENS = BLOCK_BYTES,
    STORED_MAX = 65535               /* the largest stored block */
};

#define TOK_MATCH 0x80000000u

/* Lengths 257..285 and distances 0..29: base values and extra bits (RFC 1951 3.2.5). */
static const uint16_t len_base[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,
                                      15, 17, 19, 23, 27, 31, 35, 43, 51,  59,
                                      67, 83, 99, 115, 131, 163, 195, 227, 258};
static const uint8_t len_extra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                      2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
static const uint16_t dist_base[30] = {1,    2,    3,    4,    5,    7,     9,     13,
                                       17,   25,   33,   49,   65,   97,    129,   193,
                                       257,  385,  513,  769,  1025, 1537,  2049,  3073,
                                       4097, 6145, 8193, 12289, 16385, 24577};
static const uint8_t dist_extra[30] = {0, 0, 0, 0, 1, 1, 2, 2,  3,  3,  4,  4,  5,  5,  6,
                                       6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};

/* ==================================================================================== */
/* Checksums                                                                            */
/* ==================================================================================== */

void as_crc32_table(uint32_t table[256]) {
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        table[n] = c;
    }
}

uint32_t as_crc32_update(const uint32_t table[256], uint32_t crc, const unsigned char *p,
                         size_t n) {
    uint32_t c = crc ^ 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) c = table[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
    return c ^ 0xFFFFFFFFu;
}

uint32_t as_adler32_update(uint32_t adler, const unsigned char *p, size_t n) {
    uint32_t a = adler & 0xFFFFu, b = adler >> 16;
    while (n > 0) {
        /* 5552 is the largest count for which b cannot overflow 32 bits before the
         * modulo (zlib's NMAX). */
        size_t k = n < 5552 ? n : 5552;
        n -= k;
        while (k--) {
            a += *p++;
            b += a;
        }
        a %= 65521u;
        b %= 65521u;
    }
    return b << 16 | a;
}

/* ==================================================================================== */
/* The encoder state                                                                    */
/* ==================================================================================== */

typedef struct png_enc {
    anistar_context *ctx;
    as_png_sink sink;
    void *user;
    anistar_status st; /* first failure; everything stops after it */
    uint32_t crc[256];
    /* The scanline source: the filtered stream, generated on the fly. */
    const unsigned char *pix;
    size_t row_bytes;   /* width * channels */
    uint32_t height;
    uint32_t row;       /* current row */
    size_t col;         /* 0: the filter byte is next; k > 0: row byte k - 1 is next */
    uint64_t remaining; /* bytes of the stream not yet read */
    uint32_t adler;
    /* The IDAT chunk being filled: 8 header bytes then the payload. */
    unsigned char idat[8 + AS_PNG_IDAT_MAX];
    size_t idat_n;
    /* Bit packing. */
    uint64_t bits;
    unsigned nbits;
    /* Fixed Huffman codes, bit-reversed for packing. */
    uint16_t lit_code[288];
    uint8_t lit_len[288];
    uint8_t dist_code[30];
    /* LZ77. */
    unsigned char win[WIN];
    int32_t head[HSIZE];  /* latest position of each hash, -1 none */
    int32_t prev[WSIZE];  /* previous position with the same hash, by position & WMASK */
    uint32_t tok[BLOCK_TOKENS + 1];
    size_t ntok;
    size_t pos;           /* current position in win */
    size_t look;          /* bytes available from pos */
    size_t block_start;   /* first byte of the pending block */
} png_enc;

static void st_be32(unsigned char *p, uint32_t v) {
    p[0] = (unsigned char)(v >> 24);
    p[1] = (unsigned char)(v >> 16);
    p[2] = (unsigned char)(v >> 8);
    p[3] = (unsigned char)v;
}

static void emit(png_enc *e, const unsigned char *p, size_t n) {
    if (e->st || n == 0) return;
    e->st = e->sink(e->user, p, n);
}

/* A whole chunk: length, type, data, CRC of type and data. */
static void chunk(png_enc *e, const char type[4], const unsigned char *data, size_t n) {
    unsigned char hdr[8], tail[4];
    st_be32(hdr, (uint32_t)n);
    memcpy(hdr + 4, type, 4);
    uint32_t c = as_crc32_update(e->crc, 0, hdr + 4, 4);
    c = as_crc32_update(e->crc, c, data, n);
    st_be32(tail, c);
    emit(e, hdr, 8);
    emit(e, data, n);
    emit(e, tail, 4);
}

static void idat_flush(png_enc *e) {
    if (e->idat_n == 0) return;
    chunk(e, "IDAT", e->idat + 8, e->idat_n);
    e->idat_n = 0;
}

static inline void out_byte(png_enc *e, unsigned char b) {
    e->idat[8 + e->idat_n++] = b;
    if (e->idat_n == AS_PNG_IDAT_MAX) idat_flush(e);
}

static void out_bytes(png_enc *e, const unsigned char *p, size_t n) {
    while (n > 0) {
        size_t k = AS_PNG_IDAT_MAX - e->idat_n;
        if (k > n) k = n;
        memcpy(e->idat + 8 + e->idat_n, p, k);
        e->idat_n += k;
        p += k;
        n -= k;
        if (e->idat_n == AS_PNG_IDAT_MAX) idat_flush(e);
    }
}

/* Append the n <= 32 low bits of v, least significant first. */
static inline void put_bits(png_enc *e, uint32_t v, unsigned n) {
    e->bits |= (uint64_t)v << e->nbits;
    e->nbits += n;
    while (e->nbits >= 8) {
        out_byte(e, (unsigned char)(e->bits & 0xFFu));
        e->bits >>= 8;
        e->nbits -= 8;
    }
}

static void align_byte(png_enc *e) {
    if (e->nbits > 0) put_bits(e, 0, 8 - e->nbits);
}

static uint32_t reverse_bits(uint32_t code, unsigned len) {
    uint32_t r = 0;
    for (unsigned i = 0; i < len; i++) r |= ((code >> i) & 1u) << (len - 1 - i);
    return r;
}

static void fixed_codes(png_enc *e) {
    for (unsigned s = 0; s < 288; s++) {
        uint32_t code;
        unsigned len;
        if (s < 144) {
            code = 0x30 + s;
            len = 8;
        } else if (s < 256) {
            code = 0x190 + (s - 144);
            len = 9;
        } else if (s < 280) {
            code = s - 256;
            len = 7;
        } else {
            code = 0xC0 + (s - 280);
            len = 8;
        }
        e->lit_code[s] = (uint16_t)reverse_bits(code, len);
        e->lit_len[s] = (uint8_t)len;
    }
    for (unsigned d = 0; d < 30; d++) e->dist_code[d] = (uint8_t)reverse_bits(d, 5);
}

/* The length code index (0..28) of a match length 3..258. */
static unsigned len_index(unsigned len) {
    unsigned i = 28;
    while (len_base[i] > len) i--;
    return i;
}

/* The distance code (0..29) of a distance 1..32768. */
static unsigned dist_index(unsigned dist) {
    unsigned i = 29;
    while (dist_base[i] > dist) i--;
    return i;
}

/* ==================================================================================== */
/* The scanline source                                                                  */
/* ==================================================================================== */

/* Copy up to n bytes of the filtered stream to dst (byte 0 before each row); returns
 * the count copied (< n only at the end) and updates the Adler-32. */
static size_t src_read(png_enc *e, unsigned char *dst, size_t n) {
    size_t got = 0;
    while (got < n && e->row < e->height) {
        if (e->col == 0) {
            dst[got++] = 0; /* filter type None */
            e->col = 1;
            continue;
        }
        size_t done = e->col - 1, k = e->row_bytes - done;
        if (k > n - got) k = n - got;
        memcpy(dst + got, e->pix + (size_t)e->row * e->row_bytes + done, k);
        got += k;
        e->col += k;
        if (e->col - 1 == e->row_bytes) {
            e->row++;
            e->col = 0;
        }
    }
    e->remaining -= got;
    e->adler = as_adler32_update(e->adler, dst, got);
    return got;
}

/* ==================================================================================== */
/* Deflate                                                                              */
/* ==================================================================================== */

/* A stored block of the n bytes at p (n <= 65535). */
static void stored_block(png_enc *e, const unsigned char *p, size_t n, int final) {
    put_bits(e, final ? 1u : 0u, 3); /* BFINAL, BTYPE 00 */
    align_byte(e);
    unsigned char len[4] = {(unsigned char)(n & 0xFF), (unsigned char)(n >> 8),
                            (unsigned char)(~n & 0xFF), (unsigned char)((~n >> 8) & 0xFF)};
    out_bytes(e, len, 4);
    out_bytes(e, p, n);
}

/*
 * Close the pending block (the tokens for win[block_start .. pos)): as fixed Huffman,
 * or stored when that is smaller. An empty non-final block is not written.
 */
static void flush_block(png_enc *e, int final) {
    size_t nbytes = e->pos - e->block_start;
    if (e->ntok == 0 && !final) return;
    uint64_t fixed = 3 + e->lit_len[256];
    for (size_t i = 0; i < e->ntok; i++) {
        uint32_t t = e->tok[i];
        if (t & TOK_MATCH) {
            unsigned li = len_index((t >> 16) & 0x1FFu), di = dist_index(t & 0xFFFFu);
            fixed += (uint64_t)e->lit_len[257 + li] + len_extra[li] + 5 + dist_extra[di];
        } else {
            fixed += e->lit_len[t];
        }
    }
    unsigned pad = (8 - (e->nbits + 3) % 8) % 8;
    uint64_t stored = 3 + pad + 32 + 8 * (uint64_t)nbytes;
    if (fixed > stored) {
        stored_block(e, e->win + e->block_start, nbytes, final);
    } else {
        put_bits(e, (final ? 1u : 0u) | 2u, 3); /* BFINAL, BTYPE 01 */
        for (size_t i = 0; i < e->ntok; i++) {
            uint32_t t = e->tok[i];
            if (t & TOK_MATCH) {
                unsigned len = (t >> 16) & 0x1FFu, dist = t & 0xFFFFu;
                unsigned li = len_index(len), di = dist_index(dist);
                put_bits(e, e->lit_code[257 + li], e->lit_len[257 + li]);
                if (len_extra[li]) put_bits(e, len - len_base[li], len_extra[li]);
                put_bits(e, e->dist_code[di], 5);
                if (dist_extra[di]) put_bits(e, dist - dist_base[di], dist_extra[di]);
            } else {
                put_bits(e, e->lit_code[t], e->lit_len[t]);
            }
        }
        put_bits(e, e->lit_code[256], e->lit_len[256]);
    }
    e->ntok = 0;
    e->block_start = e->pos;
}

static inline uint32_t hash3(const unsigned char *p) {
    uint32_t v = (uint32_t)p[0] << 16 | (uint32_t)p[1] << 8 | p[2];
    return (v * 2654435761u) >> (32 - HBITS);
}

static inline void insert(png_enc *e, size_t p) {
    uint32_t h = hash3(e->win + p);
    e->prev[p & WMASK] = e->head[h];
    e->head[h] = (int32_t)p;
}

/* Top up the lookahead to MIN_LOOKAHEAD bytes (or the end of the stream), sliding the
 * window by WSIZE when the position nears its end (the pending block is closed first,
 * so a block's bytes always stay in the buffer for a stored fallback). */
static void fill(png_enc *e) {
    while (e->look < MIN_LOOKAHEAD && e->remaining > 0 && !e->st) {
        if (e->pos >= (size_t)WSIZE + MAX_DIST) {
            flush_block(e, 0);
            memmove(e->win, e->win + WSIZE, (size_t)WIN - WSIZE);
            e->pos -= WSIZE;
            e->block_start -= WSIZE;
            for (size_t i = 0; i < HSIZE; i++)
                e->head[i] = e->head[i] >= WSIZE ? e->head[i] - WSIZE : -1;
            for (size_t i = 0; i < WSIZE; i++)
                e->prev[i] = e->prev[i] >= WSIZE ? e->prev[i] - WSIZE : -1;
        }
        size_t space = (size_t)WIN - (e->pos + e->look);
        e->look += src_read(e, e->win + e->pos + e->look, space);
    }
}

/*
 * Deflate the whole stream with fixed-Huffman blocks.
 * design: greedy LZ77: at each position hash the next 3 bytes, walk the chain of earlier
 *   positions with that hash (newest first, at most MAX_CHAIN, within MAX_DIST), keep
 *   the longest match (>= 3) or emit a literal; every position passed is inserted in
 *   the chains. Blocks close every BLOCK_BYTES of input and at each window slide.
 */
static void deflate_fixed(png_enc *e) {
    for (size_t i = 0; i < HSIZE; i++) e->head[i] = -1;
    for (size_t i = 0; i < WSIZE; i++) e->prev[i] = -1;
    e->pos = e->look = e->block_start = e->ntok = 0;
    fill(e);
    while (e->look > 0 && !e->st) {
        if (e->look < MIN_LOOKAHEAD) {
            fill(e);
            if (e->st) return;
        }
        size_t best = 0, best_dist = 0;
        if (e->look >= MIN_MATCH) {
            const unsigned char *a = e->win + e->pos;
            uint32_t h = hash3(a);
            int32_t cand = e->head[h];
            e->prev[e->pos & WMASK] = cand;
            e->head[h] = (int32_t)e->pos;
            size_t maxlen = e->look < MAX_MATCH ? e->look : MAX_MATCH;
            for (int chain = MAX_CHAIN; cand >= 0 && chain > 0; chain--) {
                size_t dist = e->pos - (size_t)cand;
                if (dist > MAX_DIST) break;
                const unsigned char *b = e->win + cand;
                if (b[best] == a[best]) {
                    size_t l = 0;
                    while (l < maxlen && a[l] == b[l]) l++;
                    if (l > best) {
                        best = l;
                        best_dist = dist;
                        if (l == maxlen) break;
                    }
                }
                int32_t next = e->prev[(size_t)cand & WMASK];
                if (next >= cand) break;
                cand = next;
            }
        }
        if (best >= MIN_MATCH) {
            e->tok[e->ntok++] = TOK_MATCH | (uint32_t)best << 16 | (uint32_t)best_dist;
            size_t end = e->pos + e->look;
            for (size_t k = 1; k < best; k++)
                if (e->pos + k + MIN_MATCH <= end) insert(e, e->pos + k);
            e->pos += best;
            e->look -= best;
        } else {
            e->tok[e->ntok++] = e->win[e->pos];
            e->pos++;
            e->look--;
        }
        if (e->pos - e->block_start >= BLOCK_BYTES || e->ntok == BLOCK_TOKENS)
            flush_block(e, 0);
    }
    flush_block(e, 1);
}

/* The whole stream as stored blocks of at most 65535 bytes. */
static void deflate_stored(png_enc *e) {
    while (e->remaining > 0 && !e->st) {
        size_t n = e->remaining < STORED_MAX ? (size_t)e->remaining : STORED_MAX;
        size_t got = src_read(e, e->win, n);
        stored_block(e, e->win, got, e->remaining == 0);
    }
}

/* ==================================================================================== */
/* The file                                                                             */
/* ==================================================================================== */

anistar_status as_png_encode(anistar_context *ctx, const unsigned char *pix, uint32_t width,
                             uint32_t height, int channels, as_png_compression comp,
                             as_png_sink sink, void *user) {
    if (!pix || !sink) return as_fail(ctx, ANISTAR_EINVAL, "PNG: NULL pixels or sink");
    if (width < 1 || width > AS_PNG_MAX_SIDE || height < 1 || height > AS_PNG_MAX_SIDE)
        return as_fail(ctx, ANISTAR_EINVAL, "PNG: image size %ux%u outside [1, %u]",
                       (unsigned)width, (unsigned)height, AS_PNG_MAX_SIDE);
    if (channels != 3 && channels != 4)
        return as_fail(ctx, ANISTAR_EINVAL, "PNG: %d channels (3 or 4 expected)", channels);
    if (comp != AS_PNG_STORED && comp != AS_PNG_DEFLATE)
        return as_fail(ctx, ANISTAR_EINVAL, "PNG: unknown compression %d", (int)comp);
    png_enc *e = as_alloc(ctx, sizeof *e);
    if (!e) return as_fail(ctx, ANISTAR_ENOMEM, "PNG: out of memory (%zu bytes)", sizeof *e);
    e->ctx = ctx;
    e->sink = sink;
    e->user = user;
    e->st = ANISTAR_OK;
    as_crc32_table(e->crc);
    fixed_codes(e);
    e->pix = pix;
    e->row_bytes = (size_t)width * (size_t)channels;
    e->height = height;
    e->row = 0;
    e->col = 0;
    e->remaining = (uint64_t)height * (1 + (uint64_t)e->row_bytes);
    e->adler = 1;
    e->idat_n = 0;
    e->bits = 0;
    e->nbits = 0;

    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    emit(e, signature, 8);
    unsigned char ihdr[13];
    st_be32(ihdr, width);
    st_be32(ihdr + 4, height);
    ihdr[8] = 8;                      /* bit depth */
    ihdr[9] = channels == 3 ? 2 : 6;  /* colour type: RGB / RGBA */
    ihdr[10] = 0;                     /* compression: deflate */
    ihdr[11] = 0;                     /* filter method 0 */
    ihdr[12] = 0;                     /* no interlace */
    chunk(e, "IHDR", ihdr, 13);

    /* zlib header: CM 8, CINFO 7 (32K window), FLEVEL 0 (stored) or 1 (fast). */
    out_byte(e, 0x78);
    out_byte(e, comp == AS_PNG_STORED ? 0x01 : 0x5E);
    if (comp == AS_PNG_STORED) deflate_stored(e);
    else deflate_fixed(e);
    align_byte(e);
    unsigned char adler[4];
    st_be32(adler, e->adler);
    out_bytes(e, adler, 4);
    idat_flush(e);
    chunk(e, "IEND", NULL, 0);

    anistar_status st = e->st;
    if (st == ANISTAR_OK && (e->remaining != 0 || e->row != height))
        st = as_fail(ctx, ANISTAR_EINTERNAL, "PNG: %llu scanline bytes left unencoded",
                     (unsigned long long)e->remaining);
    as_free(ctx, e, sizeof *e);
    return st;
}

/* ---- sinks ------------------------------------------------------------------------- */

typedef struct mem_sink {
    anistar_context *ctx;
    unsigned char *buf;
    size_t n, cap;
} mem_sink;

static anistar_status mem_write(void *user, const unsigned char *p, size_t n) {
    mem_sink *m = user;
    if (n > SIZE_MAX - m->n) return as_fail(m->ctx, ANISTAR_ENOMEM, "PNG: output too large");
    if (m->n + n > m->cap) {
        void *b = m->buf;
        if (as_grow(m->ctx, &b, &m->cap, m->n + n, 1))
            return as_fail(m->ctx, ANISTAR_ENOMEM, "PNG: out of memory (%zu bytes)", m->n + n);
        m->buf = b;
    }
    memcpy(m->buf + m->n, p, n);
    m->n += n;
    return ANISTAR_OK;
}

anistar_status as_png_encode_mem(anistar_context *ctx, const unsigned char *pix,
                                 uint32_t width, uint32_t height, int channels,
                                 as_png_compression comp, unsigned char **out, size_t *size) {
    if (!out || !size) return as_fail(ctx, ANISTAR_EINVAL, "PNG: NULL output");
    *out = NULL;
    *size = 0;
    mem_sink m = {ctx, NULL, 0, 0};
    anistar_status st = as_png_encode(ctx, pix, width, height, channels, comp, mem_write, &m);
    if (st == ANISTAR_OK && m.cap != m.n) {
        unsigned char *b = as_realloc(ctx, m.buf, m.cap, m.n);
        if (!b) {
            st = as_fail(ctx, ANISTAR_ENOMEM, "PNG: out of memory (%zu bytes)", m.n);
        } else {
            m.buf = b;
            m.cap = m.n;
        }
    }
    if (st) {
        as_free(ctx, m.buf, m.cap);
        return st;
    }
    *out = m.buf;
    *size = m.n;
    return ANISTAR_OK;
}

typedef struct file_sink {
    anistar_context *ctx;
    const char *path;
    FILE *f;
} file_sink;

static anistar_status file_write(void *user, const unsigned char *p, size_t n) {
    file_sink *s = user;
    errno = 0;
    if (fwrite(p, 1, n, s->f) != n)
        return as_fail(s->ctx, ANISTAR_EIO, "cannot write '%s': %s", s->path,
                       errno ? strerror(errno) : "write error");
    return ANISTAR_OK;
}

/* Remove what a failed write left at path, if it is a regular file or a symbolic link
 * (never a device, a FIFO or anything else the path may name: writing to /dev/full fails
 * and must not delete /dev/full). */
static void drop_partial(const char *path) {
    struct stat st;
    if (lstat(path, &st) == 0 && (S_ISREG(st.st_mode) || S_ISLNK(st.st_mode))) remove(path);
}

anistar_status as_png_write(anistar_context *ctx, const char *path, const unsigned char *pix,
                            uint32_t width, uint32_t height, int channels,
                            as_png_compression comp) {
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "PNG: NULL path");
    file_sink s = {ctx, path, NULL};
    errno = 0;
    s.f = fopen(path, "wb");
    if (!s.f)
        return as_fail(ctx, ANISTAR_EIO, "cannot create '%s': %s", path,
                       errno ? strerror(errno) : "unknown error");
    anistar_status st = as_png_encode(ctx, pix, width, height, channels, comp, file_write, &s);
    errno = 0;
    int close_failed = fclose(s.f) != 0;
    if (!st && close_failed)
        st = as_fail(ctx, ANISTAR_EIO, "cannot write '%s': %s", path,
                     errno ? strerror(errno) : "write error");
    if (st) drop_partial(path);
    return st;
}
