/*
 * compare_vectors.c - two files of numbers (one per line), a test output against its
 * double-precision reference, in groups of GROUP values (one group per state of the
 * vectors program): every value must satisfy |a - b| <= LSB (ABS + REL max|b|), max over
 * its group. The group's largest value is the scale of the terms each output is computed
 * from: an entry that is a small difference of large terms (a Jacobian entry near gimbal
 * lock) carries the rounding of those terms. Prints the largest errors found.
 * Usage: compare_vectors TEST REFERENCE GROUP LSB ABS REL LABEL
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define MAX_GROUP 256

int main(int argc, char **argv)
{
    FILE *a, *b;
    double lsb, abs_tol, rel_tol, worst = 0.0, worst_lsb = 0.0, va[MAX_GROUP], vb[MAX_GROUP];
    long group, n = 0, worst_n = 0, failures = 0;
    if (argc != 8) {
        fprintf(stderr, "usage: %s TEST REFERENCE GROUP LSB ABS REL LABEL\n", argv[0]);
        return 2;
    }
    group = strtol(argv[3], NULL, 10);
    lsb = strtod(argv[4], NULL);
    abs_tol = strtod(argv[5], NULL);
    rel_tol = strtod(argv[6], NULL);
    a = fopen(argv[1], "r");
    b = fopen(argv[2], "r");
    if (a == NULL || b == NULL || !(lsb > 0.0) || group < 1 || group > MAX_GROUP) {
        fprintf(stderr, "compare_vectors: cannot open the files, or bad GROUP / LSB\n");
        return 2;
    }
    for (;;) {
        double scale = 0.0;
        long i, got = 0;
        for (i = 0; i < group; ++i) {
            const int ra = fscanf(a, "%lf", &va[i]), rb = fscanf(b, "%lf", &vb[i]);
            if (ra == EOF && rb == EOF && i == 0) {
                break;
            }
            if (ra != 1 || rb != 1) {
                fprintf(stderr, "compare_vectors: files differ in length or are not whole groups (value %ld)\n",
                        n + i + 1);
                return 1;
            }
            ++got;
            if (fabs(vb[i]) > scale) {
                scale = fabs(vb[i]);
            }
        }
        if (got == 0) {
            break;
        }
        for (i = 0; i < group; ++i) {
            const double err = fabs(va[i] - vb[i]), bound = lsb * (abs_tol + rel_tol * scale);
            ++n;
            if (!(err <= bound)) {
                if (++failures <= 10) {
                    printf("value %ld: %.17g, reference %.17g, error %.3g LSB, bound %.3g LSB\n", n, va[i], vb[i],
                           err / lsb, bound / lsb);
                }
            }
            if (err / bound > worst) {
                worst = err / bound;
                worst_n = n;
            }
            if (err / lsb > worst_lsb) {
                worst_lsb = err / lsb;
            }
        }
    }
    printf("%s: %ld values; largest error %.1f LSB; largest error / bound (%g + %g max|group|) LSB: %.3f "
           "(value %ld)\n",
           argv[7], n, worst_lsb, abs_tol, rel_tol, worst, worst_n);
    if (n == 0 || failures > 0) {
        printf("FAIL (%ld values out of bound)\n", failures);
        return 1;
    }
    printf("OK\n");
    return 0;
}
