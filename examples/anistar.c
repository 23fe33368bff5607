/*
 * anistar — the command-line tool: one more client of the public API (DESIGN.md 3).
 * It parses options into API calls and nothing else.
 */
#include "anistar.h"

#include <stdio.h>
#include <string.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: anistar COMMAND [options]\n"
            "       anistar --help | --version\n");
}

int main(int argc, char **argv) {
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("anistar %s\n", anistar_version());
        return 0;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        usage(stdout);
        return 0;
    }
    fprintf(stderr, "anistar: unknown command '%s' (try --help)\n", argv[1]);
    return 2;
}
