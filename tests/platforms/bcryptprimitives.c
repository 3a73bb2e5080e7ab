/* A stand-in for Windows' bcryptprimitives.dll, for running the win64 binaries under Wine
   8.0, which lacks that DLL (Windows 10 and later have it). Rust's standard library
   draws its random numbers (HashMap seeds) from its ProcessPrng; this forwards to
   RtlGenRandom, which Wine has. Used by the tests only: it is never packed in the FMU. */

#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x10000000 ? 0x10000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk)) return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
