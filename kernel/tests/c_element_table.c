/* The element kinds of mbdk.h must be the kernel's registry (mbdk_element_kind), name by name:
 * every kernel kind has its enum value here and every enum value here is a kernel kind.
 * (tests/test_elements.py does the same for Python.) Exit code 0 = pass. */
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

struct entry { int cls; const char *name; int code; };

int main(void)
{
    const struct entry header[] = {
        {MBDK_CLASS_JOINT, "revolute", MBDK_JOINT_REVOLUTE},
        {MBDK_CLASS_JOINT, "prismatic", MBDK_JOINT_PRISMATIC},
        {MBDK_CLASS_JOINT, "fixed", MBDK_JOINT_FIXED},
        {MBDK_CLASS_JOINT, "driver", MBDK_JOINT_DRIVER},
        {MBDK_CLASS_JOINT, "distance", MBDK_JOINT_DISTANCE},
        {MBDK_CLASS_JOINT, "point_line", MBDK_JOINT_POINT_LINE},
        {MBDK_CLASS_JOINT, "point_curve", MBDK_JOINT_POINT_CURVE},
        {MBDK_CLASS_JOINT, "coupling", MBDK_JOINT_COUPLING},
        {MBDK_CLASS_JOINT, "rolling", MBDK_JOINT_ROLLING},
        {MBDK_CLASS_JOINT, "knife_edge", MBDK_JOINT_KNIFE_EDGE},
        {MBDK_CLASS_FORCE, "gravity", MBDK_FORCE_GRAVITY},
        {MBDK_CLASS_FORCE, "point_force", MBDK_FORCE_POINT},
        {MBDK_CLASS_FORCE, "torque", MBDK_FORCE_TORQUE},
        {MBDK_CLASS_FORCE, "spring_damper", MBDK_FORCE_SPRING_DAMPER},
        {MBDK_CLASS_FORCE, "coordinate_spring_damper", MBDK_FORCE_COORDINATE},
        {MBDK_CLASS_FORCE, "spring", MBDK_FORCE_SPRING},
        {MBDK_CLASS_FORCE, "damper", MBDK_FORCE_DAMPER},
        {MBDK_CLASS_FORCE, "contact", MBDK_FORCE_CONTACT},
        {MBDK_CLASS_FORCE, "friction", MBDK_FORCE_FRICTION},
        {MBDK_CLASS_EFFECT, "wear", MBDK_EFFECT_WEAR},
    };
    const int nh = sizeof header / sizeof header[0];
    int bad = 0, n = 0, cls, code, rows, states;
    char name[64];
    for (int i = 1; mbdk_element_kind(i, &cls, &code, name, sizeof name, &rows, &states) == MBDK_SUCCESS; i++) {
        int found = 0;
        n++;
        for (int k = 0; k < nh; k++)
            if (strcmp(header[k].name, name) == 0) {
                found = 1;
                if (header[k].cls != cls || header[k].code != code) {
                    printf("%s: kernel class %d code %d, mbdk.h class %d code %d\n", name, cls,
                           code, header[k].cls, header[k].code);
                    bad++;
                }
            }
        if (!found) { printf("kernel kind %s is not in mbdk.h\n", name); bad++; }
    }
    if (n != nh) { printf("kernel has %d kinds, mbdk.h %d\n", n, nh); bad++; }

    /* body kinds: the enum against the kernel's body table, and planar bodies are available */
    const struct entry bodies[] = {{0, "planar", MBDK_BODY_PLANAR}, {0, "spatial", MBDK_BODY_SPATIAL}};
    const int nbk = sizeof bodies / sizeof bodies[0];
    int nk = 0, coords, vels, avail;
    for (int i = 1; mbdk_body_kind(i, &code, name, sizeof name, &coords, &vels, &avail) == MBDK_SUCCESS; i++) {
        int found = 0;
        nk++;
        for (int k = 0; k < nbk; k++)
            if (strcmp(bodies[k].name, name) == 0) {
                found = 1;
                if (bodies[k].code != code) {
                    printf("body kind %s: kernel code %d, mbdk.h %d\n", name, code, bodies[k].code);
                    bad++;
                }
            }
        if (!found) { printf("kernel body kind %s is not in mbdk.h\n", name); bad++; }
        if (code == MBDK_BODY_PLANAR && !(coords == 3 && vels == 3 && avail == 1)) {
            printf("planar bodies: %d coordinates, %d velocities, available %d\n", coords, vels, avail);
            bad++;
        }
    }
    if (nk != nbk) { printf("kernel has %d body kinds, mbdk.h %d\n", nk, nbk); bad++; }
    if (mbdk_body_kind(1, NULL, name, sizeof name, &coords, &vels, &avail) != MBDK_ERR_INVALID_INPUT) {
        printf("mbdk_body_kind accepted a NULL pointer\n");
        bad++;
    }
    printf("%d kinds, %d mismatches\n", n, bad);
    return bad != 0;
}
