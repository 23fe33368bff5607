/*
 * png.h — internal: a dependency-free PNG encoder (DESIGN.md 1, the io layer): 8-bit RGB
 * or RGBA images, no zlib.
 *
 * The file is: the signature, IHDR (bit depth 8, colour type 2 = RGB or 6 = RGBA, no
 * interlace), IDAT chunks of at most AS_PNG_IDAT_MAX bytes, IEND. Every scanline gets
 * filter byte 0 (None). The zlib stream (RFC 1950: header 78 01 or 78 5E, deflate data,
 * big-endian Adler-32 of the filtered scanlines) holds, depending on the compression:
 *   AS_PNG_STORED   stored deflate blocks (RFC 1951 3.2.4) of at most 65535 bytes;
 *   AS_PNG_DEFLATE  blocks with the fixed Huffman codes (RFC 1951 3.2.6), matches found
 *                   by LZ77 with hash chains over a 32 KiB window (greedy parsing); any
 *                   block that would come out larger than stored is written stored.
 * The output is a pure function of the pixels and the options (no time stamp): the same
 * image gives the same bytes.
 *
 * Memory: the encoder streams. It needs about 400 KiB of work space (window, hash
 * chains, one block of tokens, one IDAT chunk) whatever the image size, and reads the
 * pixels in place.
 *
 * The CRC-32 (PNG chunks) and Adler-32 (zlib) checksums are exposed for the tests.
 */
#ifndef ANISTAR_PNG_H
#define ANISTAR_PNG_H

#include "core.h"

#include <stddef.h>
#include <stdint.h>

/* The largest width and height accepted (the PNG format allows 2^31 - 1). */
#define AS_PNG_MAX_SIDE 16384u
/* The largest IDAT payload written (bytes). */
#define AS_PNG_IDAT_MAX 65536u

typedef enum as_png_compression {
    AS_PNG_STORED = 0, /* stored blocks: fast, file = raw size + ~0.01% */
    AS_PNG_DEFLATE = 1 /* fixed-Huffman LZ77 (never larger than stored + 5 bytes/block) */
} as_png_compression;

/*
 * Where the encoded bytes go: return ANISTAR_OK, or a failure status after recording
 * the message in the context (the encoder stops and returns that status).
 */
typedef anistar_status (*as_png_sink)(void *user, const unsigned char *p, size_t n);

/*
 * Encode the image pix (height rows of width pixels of `channels` bytes, 3 = RGB or
 * 4 = RGBA, rows contiguous, top row first) and hand the bytes to sink in order.
 * Returns EINVAL (a NULL pointer, width or height outside [1, AS_PNG_MAX_SIDE], channels
 * not 3 or 4, an unknown compression), ENOMEM, or the sink's failure.
 * design: signature, IHDR -> the zlib stream of the filtered scanlines (the byte 0 then
 *   the row, generated on the fly), deflated block by block (as_png_compression) into
 *   IDAT chunks as they fill -> IEND. Checksums: CRC-32 from a 256-entry table computed
 *   at the start of each call (no global state), Adler-32 updated as scanline bytes are
 *   generated.
 */
anistar_status as_png_encode(anistar_context *ctx, const unsigned char *pix, uint32_t width,
                             uint32_t height, int channels, as_png_compression comp,
                             as_png_sink sink, void *user);

/*
 * The same into memory: on success *out holds *size bytes allocated from ctx (free
 * with as_free(ctx, *out, *size)); on failure *out is NULL and *size 0.
 */
anistar_status as_png_encode_mem(anistar_context *ctx, const unsigned char *pix,
                                 uint32_t width, uint32_t height, int channels,
                                 as_png_compression comp, unsigned char **out, size_t *size);

/*
 * The same into the file path (created or truncated). EIO "cannot create 'path': ..."
 * or "cannot write 'path': ..." (with strerror) when the file cannot be created or a
 * write or the close fails. After any failure the partial file is removed when path is
 * a regular file or a symbolic link (never a device or a FIFO).
 */
anistar_status as_png_write(anistar_context *ctx, const char *path, const unsigned char *pix,
                            uint32_t width, uint32_t height, int channels,
                            as_png_compression comp);

/* Checksums: start with crc = 0 (adler = 1) and feed the bytes in pieces if needed.
 * as_crc32_table fills the table of the reflected polynomial 0xEDB88320. */
void as_crc32_table(uint32_t table[256]);
uint32_t as_crc32_update(const uint32_t table[256], uint32_t crc, const unsigned char *p,
                         size_t n);
uint32_t as_adler32_update(uint32_t adler, const unsigned char *p, size_t n);

#endif /* ANISTAR_PNG_H */
