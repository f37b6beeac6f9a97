/* c_status_table.c - the codes in mbdk.h must equal the kernel's status table, name by name.
 * (tests/test_status.py does the same for Python.) Exit code 0 = pass. */
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

struct entry { const char *name; int code; };

int main(void)
{
    const struct entry header[] = {
        {"SUCCESS", MBDK_SUCCESS},
        {"NOTE_LAST_STEP_SHORTENED", MBDK_NOTE_LAST_STEP_SHORTENED},
        {"ERR_INVALID_INPUT", MBDK_ERR_INVALID_INPUT},
        {"ERR_UNKNOWN_METHOD", MBDK_ERR_UNKNOWN_METHOD},
        {"ERR_UNKNOWN_PROBLEM", MBDK_ERR_UNKNOWN_PROBLEM},
        {"ERR_NOT_APPLICABLE", MBDK_ERR_NOT_APPLICABLE},
        {"ERR_OUTPUT_SIZE", MBDK_ERR_OUTPUT_SIZE},
        {"ERR_INCONSISTENT_INITIAL", MBDK_ERR_INCONSISTENT_INITIAL},
        {"ERR_NO_MEMORY", MBDK_ERR_NO_MEMORY},
        {"ERR_STEP_TOO_SMALL", MBDK_ERR_STEP_TOO_SMALL},
        {"ERR_TOO_MANY_STEPS", MBDK_ERR_TOO_MANY_STEPS},
        {"ERR_TOO_MUCH_ACCURACY", MBDK_ERR_TOO_MUCH_ACCURACY},
        {"ERR_NEWTON_DIVERGED", MBDK_ERR_NEWTON_DIVERGED},
        {"ERR_SINGULAR_MATRIX", MBDK_ERR_SINGULAR_MATRIX},
        {"ERR_NONFINITE", MBDK_ERR_NONFINITE},
        {"ERR_CONSTRAINT_DRIFT", MBDK_ERR_CONSTRAINT_DRIFT},
        {"ERR_ENERGY_DRIFT", MBDK_ERR_ENERGY_DRIFT},
        {"ERR_CONTACT_OVERRUN", MBDK_ERR_CONTACT_OVERRUN},
        {"ERR_INVARIANT_DRIFT", MBDK_ERR_INVARIANT_DRIFT},
        {"ERR_CALLBACK_FAILED", MBDK_ERR_CALLBACK_FAILED},
        {"ERR_BACKEND", MBDK_ERR_BACKEND},
        {"ERR_INTERRUPTED", MBDK_ERR_INTERRUPTED},
    };
    const int nheader = (int)(sizeof header / sizeof header[0]);
    int i, code, nkernel = 0, fails = 0;
    char name[64];
    for (i = 1; mbdk_status_entry(i, &code, name, sizeof name) == MBDK_SUCCESS; i++) {
        int found = 0;
        nkernel++;
        for (int j = 0; j < nheader; j++) {
            if (strcmp(header[j].name, name) == 0) {
                found = 1;
                if (header[j].code != code) {
                    printf("MISMATCH %s: kernel %d, mbdk.h %d\n", name, code, header[j].code);
                    fails++;
                }
            }
        }
        if (!found) { printf("MISSING in mbdk.h: %s = %d\n", name, code); fails++; }
    }
    if (nkernel != nheader) { printf("kernel has %d codes, mbdk.h %d\n", nkernel, nheader); fails++; }
    printf("%d status codes compared: %s\n", nkernel, fails ? "FAIL" : "PASS");
    return fails ? 1 : 0;
}
