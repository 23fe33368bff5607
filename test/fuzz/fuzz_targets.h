/*
 * fuzz_targets.h — the shared "run one input" functions of the reader fuzzers (issue 5,
 * part 7). Used by the libFuzzer harnesses test/fuzz/fuzz_<reader>.c and by the corpus
 * replay test test/test_fuzz_corpus.c (which #includes fuzz_targets.c directly, since
 * the Makefile links only the files of test/common into the tests).
 *
 * Each run creates a fresh context with a counting allocator, feeds the input to one
 * reader, checks what the reader promises (a valid status: OK, or an error with a
 * non-empty message; on success an output that satisfies the reader's contract), frees
 * everything and checks that every allocated byte came back.
 */
#ifndef ANISTAR_FUZZ_TARGETS_H
#define ANISTAR_FUZZ_TARGETS_H

#include <stddef.h>
#include <stdint.h>

typedef enum ft_reader {
    FT_OFF,
    FT_OBJ,
    FT_PLY,
    FT_STL,
    FT_MEDIT,
    FT_SOL,
    FT_INR,
    FT_NRRD,
    FT_METAIMAGE,
    FT_EXPR,
    FT_VTK,
    FT_VTU,
    FT_MESHB,
    FT_SOLB,
    FT_READER_COUNT
} ft_reader;

/* The reader's name, which is also its corpus directory name under test/fuzz/corpus/
 * ("off", "obj", "ply", "stl", "medit", "sol", "inr", "nrrd", "metaimage", "expr", "vtk",
 * "vtu", "meshb", "solb"). */
const char *ft_reader_name(ft_reader r);
/* The reader named name, or FT_READER_COUNT if none. */
ft_reader ft_reader_by_name(const char *name);

/* The outcome of one run. ok == 1: every check passed. Otherwise what names the first
 * violated property (a static string or a string in the result's buffer). status is
 * the reader's status (an anistar_status value). */
typedef struct ft_result {
    int ok;
    int status;
    const char *what;
    char buf[256];
} ft_result;

/* Run reader r on data[0, size) (copied: the harness adds the '\0' sentinel the mesh
 * parsers need; image readers get the bytes through a temporary file). */
void ft_run(ft_reader r, const uint8_t *data, size_t size, ft_result *res);

#endif /* ANISTAR_FUZZ_TARGETS_H */
