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

/* Which sanitizer the test was built with, printed so that a log shows it really ran. */
#if defined(__SANITIZE_ADDRESS__)
#define TROUPE_TEST_SANITIZER "address"
#elif defined(__SANITIZE_THREAD__)
#define TROUPE_TEST_SANITIZER "thread"
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define TROUPE_TEST_SANITIZER "address"
#elif __has_feature(thread_sanitizer)
#define TROUPE_TEST_SANITIZER "thread"
#endif
#endif
#ifndef TROUPE_TEST_SANITIZER
#define TROUPE_TEST_SANITIZER "none"
#endif

#endif
