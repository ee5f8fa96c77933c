/* lean_libs.c: smaller stand-ins for four pieces of the toolchain's libraries, for the Cortex-M0 image only
 * (make -C firmware board-m0); each gives the same results as the piece it replaces.
 *
 * - __aeabi_fsub (float a - b): libgcc's Thumb-1 build links its own copy of the soft-float adder for subtraction
 *   (subsf3.o, 0.8 KB beside addsf3.o). IEEE 754 defines a - b as a + (-b), and libgcc's soft-fp computes it so
 *   (soft-fp/op-common.h, _FP_SUB: B's sign flipped, then _FP_ADD_INTERNAL; only a NaN's sign bit can differ): here
 *   the sign bit of b is flipped and the one adder called.
 * - __eqsf2, __nesf2, __lesf2, __ltsf2 (the float comparisons behind __aeabi_fcmp*): libgcc links three soft-fp
 *   comparators (eqsf2.o, lesf2.o, gesf2.o; 0.4 KB) that differ only in what they answer for unordered operands.
 *   __gesf2(a, b) answers -1, 0, 1 for a < b, a == b, a > b and -2 when either is a NaN (soft-fp's FP_CMP with
 *   un = -2); so __lesf2(a, b) = -__gesf2(b, a) gives lesf2's own answers (un = 2), and a == b exactly when
 *   __gesf2(a, b) is 0 (eqsf2's 0 for equal, nonzero otherwise, NaNs included). The __lt/__ne names are the same
 *   objects' second entry points.
 * - expf, logf, atan2f, sqrtf: newlib's wrappers (wf_*.c) call __ieee754_*f and then set errno on a domain or range
 *   error; the board never reads errno, so these call the same __ieee754_*f and return its result unchanged (the
 *   wrappers' own results in IEEE mode), and errno's reentrancy struct (96 B of flash and RAM) is not linked.
 */
#include <stdint.h>
#include <string.h>

float __aeabi_fadd(float a, float b);
float __aeabi_fsub(float a, float b);
int __gesf2(float a, float b);
int __lesf2(float a, float b);
int __ltsf2(float a, float b);
int __eqsf2(float a, float b);
int __nesf2(float a, float b);
float __ieee754_expf(float x);
float __ieee754_logf(float x);
float __ieee754_atan2f(float y, float x);
float __ieee754_sqrtf(float x);
float expf(float x);
float logf(float x);
float atan2f(float y, float x);
float sqrtf(float x);

float __aeabi_fsub(float a, float b)
{
    uint32_t bits;
    memcpy(&bits, &b, sizeof bits);
    bits ^= 0x80000000u;
    memcpy(&b, &bits, sizeof b);
    return __aeabi_fadd(a, b);
}

int __lesf2(float a, float b)
{
    return -__gesf2(b, a);
}

int __ltsf2(float a, float b)
{
    return -__gesf2(b, a);
}

int __eqsf2(float a, float b)
{
    return __gesf2(a, b) != 0;
}

int __nesf2(float a, float b)
{
    return __gesf2(a, b) != 0;
}

float expf(float x)
{
    return __ieee754_expf(x);
}

float logf(float x)
{
    return __ieee754_logf(x);
}

float atan2f(float y, float x)
{
    return __ieee754_atan2f(y, x);
}

float sqrtf(float x)
{
    return __ieee754_sqrtf(x);
}
