/*
 * compare_scenarios.c - float vs double build on the same scenario (att_scenario): every
 * Euler angle of every sample within TOL rad (angle differences wrapped into [-pi, pi)).
 * Usage: compare_scenarios FLOAT_OUTPUT DOUBLE_OUTPUT [TOL [LABEL]]. Prints the largest
 * difference. TOL (rad) defaults to 1e-4; the fixed-point build is checked with its own.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define TOL 1e-4 /* rad */

int main(int argc, char **argv)
{
    FILE *a, *b;
    double worst = 0.0, worst_t = 0.0, tol = TOL;
    const char *label = (argc > 4) ? argv[4] : "float vs double";
    long n = 0;
    if (argc < 3 || argc > 5) {
        fprintf(stderr, "usage: %s FLOAT_OUTPUT DOUBLE_OUTPUT [TOL [LABEL]]\n", argv[0]);
        return 2;
    }
    if (argc > 3) {
        char *end = NULL;
        tol = strtod(argv[3], &end);
        if (end == argv[3] || *end != '\0' || !(tol > 0.0)) {
            fprintf(stderr, "compare_scenarios: bad tolerance '%s'\n", argv[3]);
            return 2;
        }
    }
    a = fopen(argv[1], "r");
    b = fopen(argv[2], "r");
    if (a == NULL || b == NULL) {
        fprintf(stderr, "compare_scenarios: cannot open %s\n", a == NULL ? argv[1] : argv[2]);
        return 2;
    }
    for (;;) {
        double ta, tb, ea[3], eb[3];
        int i;
        const int ra = fscanf(a, "%lf %lf %lf %lf", &ta, &ea[0], &ea[1], &ea[2]);
        const int rb = fscanf(b, "%lf %lf %lf %lf", &tb, &eb[0], &eb[1], &eb[2]);
        if (ra == EOF && rb == EOF) {
            break;
        }
        if (ra != 4 || rb != 4 || fabs(ta - tb) > 1e-9) {
            fprintf(stderr, "compare_scenarios: outputs differ in length or timing at line %ld\n", n + 1);
            return 1;
        }
        for (i = 0; i < 3; ++i) {
            const double d = fabs(remainder(ea[i] - eb[i], 6.283185307179586));
            if (d > worst) {
                worst = d;
                worst_t = ta;
            }
        }
        ++n;
    }
    printf("%s: %ld samples, max Euler-angle difference %.3e rad at t = %.2f s (tolerance %.0e)\n", label, n,
           worst, worst_t, tol);
    if (n == 0 || worst > tol) {
        printf("FAIL\n");
        return 1;
    }
    printf("OK\n");
    return 0;
}
