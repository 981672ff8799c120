/* The assertion macros of the C and C++ ABI tests: count checks, report each failure with the
 * library's last error message, and let main() print "N passed, M failed". */
#ifndef TROUPE_TEST_CHECK_H
#define TROUPE_TEST_CHECK_H

#include <stdio.h>

#include "troupe.h"

static int passed = 0, failed = 0;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (cond) {                                                                  \
            passed++;                                                                \
        } else {                                                                     \
            failed++;                                                                \
            fprintf(stderr, "%s:%d: CHECK(%s) failed; last error: %s\n", __FILE__,   \
                    __LINE__, #cond,                                                 \
                    troupe_last_error_message() ? troupe_last_error_message() : "-"); \
        }                                                                            \
    } while (0)

#define EXPECT(call, status) CHECK((call) == (status))

#endif
