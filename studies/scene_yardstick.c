/* The yardstick of studies/scene_drift.py (table scene_speed): rk4 on the double pendulum in
   absolute coordinates, reduced formulation, written out by hand for this one mechanism. The
   kernel's arithmetic (S = D W D^T, block LDL^T with the two joints as pivot blocks,
   a = W (f - D^T lam)) with nothing table-driven: what the generality costs.
   argv: n h y0[12] m1 I1 m2 I2 sO[2] gO[2] sA2[2] sA1[2] g[2]
   (joint O: bar1 point sO on the ground point gO; joint A: bar2 point sA2 on bar1 point sA1).
   Prints the CPU time of the loop and the final state. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double W[6], FQ[6], SO[2], GO[2], SA2[2], SA1[2];

static void f(const double *y, double *out) {
    double c1 = cos(y[2]), s1 = sin(y[2]), c2 = cos(y[5]), s2 = sin(y[5]);
    double ro0 = c1 * SO[0] - s1 * SO[1], ro1 = s1 * SO[0] + c1 * SO[1];
    double r20 = c2 * SA2[0] - s2 * SA2[1], r21 = s2 * SA2[0] + c2 * SA2[1];
    double r10 = c1 * SA1[0] - s1 * SA1[1], r11 = s1 * SA1[0] + c1 * SA1[1];
    double w1 = y[8] * y[8], w2 = y[11] * y[11];
    /* theta entries of D: row 0,1 (joint O) on bar1; rows 2,3 (joint A) on bar2 and bar1 */
    double d0 = -ro1, d1 = ro0, d2b = -r21, d2a = r11, d3b = r20, d3a = -r10;
    double g0 = w1 * ro0, g1 = w1 * ro1, g2 = w2 * r20 - w1 * r10, g3 = w2 * r21 - w1 * r11;
    double s00 = W[0] + W[2] * d0 * d0, s10 = W[2] * d0 * d1, s11 = W[1] + W[2] * d1 * d1;
    double s20 = -W[0] + W[2] * d0 * d2a, s21 = W[2] * d1 * d2a;
    double s30 = W[2] * d0 * d3a, s31 = -W[1] + W[2] * d1 * d3a;
    double s22 = W[3] + W[5] * d2b * d2b + W[0] + W[2] * d2a * d2a;
    double s32 = W[5] * d2b * d3b + W[2] * d2a * d3a;
    double s33 = W[4] + W[5] * d3b * d3b + W[1] + W[2] * d3a * d3a;
    double b0 = W[0] * FQ[0] + d0 * W[2] * FQ[2] - g0;
    double b1 = W[1] * FQ[1] + d1 * W[2] * FQ[2] - g1;
    double b2 = W[3] * FQ[3] + d2b * W[5] * FQ[5] - W[0] * FQ[0] + d2a * W[2] * FQ[2] - g2;
    double b3 = W[4] * FQ[4] + d3b * W[5] * FQ[5] - W[1] * FQ[1] + d3a * W[2] * FQ[2] - g3;
    /* first pivot block (joint O), its inverse; L = S(2:3, 0:1) B^-1; trailing update */
    double y1 = 1.0 / (s00 * s11 - s10 * s10);
    double i00 = s11 * y1, i11 = s00 * y1, i10 = -s10 * y1;
    double l20 = s20 * i00 + s21 * i10, l21 = s20 * i10 + s21 * i11;
    double l30 = s30 * i00 + s31 * i10, l31 = s30 * i10 + s31 * i11;
    s22 -= s20 * l20 + s21 * l21;
    s32 -= s30 * l20 + s31 * l21;
    s33 -= s30 * l30 + s31 * l31;
    b2 -= l20 * b0 + l21 * b1;
    b3 -= l30 * b0 + l31 * b1;
    double y2 = 1.0 / (s22 * s33 - s32 * s32);
    double m2 = (s33 * b2 - s32 * b3) * y2, m3 = (s22 * b3 - s32 * b2) * y2;
    double x0 = b0 - s20 * m2 - s30 * m3, x1 = b1 - s21 * m2 - s31 * m3;
    double m0 = i00 * x0 + i10 * x1, m1 = i10 * x0 + i11 * x1;
    for (int i = 0; i < 6; i++) out[i] = y[6 + i];
    out[6] = W[0] * (FQ[0] - m0 + m2);
    out[7] = W[1] * (FQ[1] - m1 + m3);
    out[8] = W[2] * (FQ[2] - d0 * m0 - d1 * m1 - d2a * m2 - d3a * m3);
    out[9] = W[3] * (FQ[3] - m2);
    out[10] = W[4] * (FQ[4] - m3);
    out[11] = W[5] * (FQ[5] - d2b * m2 - d3b * m3);
}

int main(int argc, char **argv) {
    if (argc != 3 + 12 + 14) return 2;
    long n = atol(argv[1]);
    double h = atof(argv[2]), y[12], p[14], k1[12], k2[12], k3[12], k4[12], t[12];
    for (int i = 0; i < 12; i++) y[i] = atof(argv[3 + i]);
    for (int i = 0; i < 14; i++) p[i] = atof(argv[15 + i]);
    double m1 = p[0], in1 = p[1], m2 = p[2], in2 = p[3];
    W[0] = W[1] = 1.0 / m1; W[2] = 1.0 / in1; W[3] = W[4] = 1.0 / m2; W[5] = 1.0 / in2;
    SO[0] = p[4]; SO[1] = p[5]; GO[0] = p[6]; GO[1] = p[7];
    SA2[0] = p[8]; SA2[1] = p[9]; SA1[0] = p[10]; SA1[1] = p[11];
    FQ[0] = m1 * p[12]; FQ[1] = m1 * p[13]; FQ[2] = 0.0;
    FQ[3] = m2 * p[12]; FQ[4] = m2 * p[13]; FQ[5] = 0.0;
    struct timespec a, b;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
    for (long s = 0; s < n; s++) {
        f(y, k1);
        for (int i = 0; i < 12; i++) t[i] = y[i] + 0.5 * h * k1[i];
        f(t, k2);
        for (int i = 0; i < 12; i++) t[i] = y[i] + 0.5 * h * k2[i];
        f(t, k3);
        for (int i = 0; i < 12; i++) t[i] = y[i] + h * k3[i];
        f(t, k4);
        for (int i = 0; i < 12; i++) y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
    printf("%.9e", (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec));
    for (int i = 0; i < 12; i++) printf(" %.17g", y[i]);
    printf("\n");
    return 0;
}
