/* The header compiles on its own, as C99 and as C++17, with every warning an error. */
#include "troupe.h"

int main(void) {
    return troupe_abi_version() == TROUPE_ABI_VERSION ? 0 : 1;
}
