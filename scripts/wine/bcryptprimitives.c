/* ProcessPrng for Wine releases that lack bcryptprimitives.dll (Wine 8, Debian 12's): Rust's
 * standard library (1.78 and later) takes its random seeds from it on Windows, so a Rust
 * program will not start without it. Real Windows (10 and later) has the DLL; this shim only
 * ever goes into the Wine prefix scripts/platform-run.sh makes, never into a package.
 * It draws from RtlGenRandom (advapi32's SystemFunction036), which Wine implements. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk)) return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
