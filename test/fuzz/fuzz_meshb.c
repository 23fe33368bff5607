/* fuzz_meshb.c — libFuzzer harness for the meshb reader (see fuzz_targets.h, README.md). */
#include "fuzz_targets.h"

#include <stdio.h>
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    ft_result res;
    ft_run(FT_MESHB, data, size, &res);
    if (!res.ok) {
        fprintf(stderr, "fuzz_meshb: %s (status %d)\n", res.what, res.status);
        abort();
    }
    return 0;
}
