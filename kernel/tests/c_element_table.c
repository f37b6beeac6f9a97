/* The element kinds of mbdk.h must be the kernel's registry (mbdk_element_kind), name by name:
 * every kernel kind has its enum value here and every enum value here is a kernel kind, one name
 * has one code (the registry holds planar and spatial kinds in one table), a kind applies to
 * known body kinds only and a joint has constraint rows on exactly the body kinds it applies to.
 * (tests/test_elements.py and tests/test_codes.py do the same for Python.) Exit code 0 = pass. */
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
        {MBDK_CLASS_JOINT, "spherical", MBDK_JOINT_SPHERICAL},
        {MBDK_CLASS_JOINT, "universal", MBDK_JOINT_UNIVERSAL},
        {MBDK_CLASS_JOINT, "cylindrical", MBDK_JOINT_CYLINDRICAL},
        {MBDK_CLASS_JOINT, "angle_driver", MBDK_JOINT_ANGLE_DRIVER},
        {MBDK_CLASS_JOINT, "slide_driver", MBDK_JOINT_SLIDE_DRIVER},
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
        {MBDK_CLASS_FORCE, "sphere_plane", MBDK_FORCE_SPHERE_PLANE},
        {MBDK_CLASS_FORCE, "sphere_sphere", MBDK_FORCE_SPHERE_SPHERE},
    };
    enum { NMAX = 64 };
    const int nh = sizeof header / sizeof header[0];
    const int known = MBDK_ON_PLANAR | MBDK_ON_SPATIAL;
    int bad = 0, n = 0, cls, code, on, rows[MBDK_BODY_KINDS], states;
    int seen_table[NMAX], seen_code[NMAX];
    char name[64], seen_name[NMAX][64];
    for (int i = 1; mbdk_element_kind(i, &cls, &code, name, sizeof name, &on, rows, &states) == MBDK_SUCCESS; i++) {
        int found = 0;
        /* joints are one table, forces and effects share the other */
        int table = cls == MBDK_CLASS_JOINT ? 1 : 2;
        if (n == NMAX) { printf("more than %d kinds\n", NMAX); return 1; }
        for (int k = 0; k < n; k++) {
            if (strcmp(seen_name[k], name) == 0) { printf("%s: two entries\n", name); bad++; }
            if (seen_table[k] == table && seen_code[k] == code) {
                printf("%s and %s: one code %d\n", seen_name[k], name, code);
                bad++;
            }
        }
        strcpy(seen_name[n], name);
        seen_table[n] = table;
        seen_code[n] = code;
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
        if (on == 0 || (on & ~known) != 0) {
            printf("%s: applies to body kinds %d (known bits: %d)\n", name, on, known);
            bad++;
        }
        for (int k = 1; k <= MBDK_BODY_KINDS; k++) {
            int applies = (on >> (k - 1)) & 1;
            int want_rows = cls == MBDK_CLASS_JOINT && applies;
            if ((rows[k - 1] > 0) != want_rows || rows[k - 1] < 0) {
                printf("%s: %d rows on body kind %d, applies %d\n", name, rows[k - 1], k, applies);
                bad++;
            }
        }
    }
    if (n != nh) { printf("kernel has %d kinds, mbdk.h %d\n", n, nh); bad++; }
    if (mbdk_element_kind(1, &cls, &code, name, sizeof name, &on, NULL, &states) != MBDK_ERR_INVALID_INPUT) {
        printf("mbdk_element_kind accepted a NULL pointer\n");
        bad++;
    }

    /* body kinds: the enum against the kernel's body table; both kinds run in a model */
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
        if (avail != 1) { printf("body kind %s: available %d\n", name, avail); bad++; }
        if (code == MBDK_BODY_PLANAR && !(coords == 3 && vels == 3)) {
            printf("planar bodies: %d coordinates, %d velocities\n", coords, vels);
            bad++;
        }
    }
    if (nk != nbk || nk != MBDK_BODY_KINDS) {
        printf("kernel has %d body kinds, mbdk.h %d (MBDK_BODY_KINDS %d)\n", nk, nbk, MBDK_BODY_KINDS);
        bad++;
    }
    if (mbdk_body_kind(1, NULL, name, sizeof name, &coords, &vels, &avail) != MBDK_ERR_INVALID_INPUT) {
        printf("mbdk_body_kind accepted a NULL pointer\n");
        bad++;
    }
    printf("%d kinds, %d mismatches\n", n, bad);
    return bad != 0;
}
