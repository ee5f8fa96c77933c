/* lean_libs.c: smaller stand-ins for five pieces of the toolchain's libraries, for the Cortex-M0 image only
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
 * - the 32-bit integer divisions (__aeabi_uidiv, __aeabi_uidivmod, __aeabi_idiv, __aeabi_idivmod and their
 *   __udivsi3/__divsi3 names): libgcc's Thumb-1 ones are unrolled (0.74 KB); this is the schoolbook shift and
 *   subtract over the quotient's bits only, 0.2 KB. Slower for a long quotient (about 10 cycles a bit against
 *   libgcc's 4); the board's divisions are mostly short ones (the loop's, a quotient of 0 or 1): 0.2 % more
 *   CPU in the emulated loop (fcb_sim.hosts.m0boot). C's results: truncated quotients, remainders with the
 *   dividend's sign, INT_MIN / -1 = INT_MIN as ARM's own; a zero divisor gives 0 (libgcc's __aeabi_idiv0 path
 *   returns 0 too) and the dividend as remainder. Built outside LTO (the Makefile says why).
 * - expf, logf, atan2f, sqrtf: newlib's wrappers (wf_*.c) call __ieee754_*f and then set errno on a domain or range
 *   error; the board never reads errno, so these call the same __ieee754_*f and return its result unchanged (the
 *   wrappers' own results in IEEE mode), and errno's reentrancy struct (96 B of flash and RAM) is not linked.
 */
#include <stdint.h>
#include <string.h>

uint32_t __udivsi3(uint32_t n, uint32_t d);
uint32_t __aeabi_uidiv(uint32_t n, uint32_t d);
uint64_t __aeabi_uidivmod(uint32_t n, uint32_t d);
int32_t __divsi3(int32_t n, int32_t d);
int32_t __aeabi_idiv(int32_t n, int32_t d);
int64_t __aeabi_idivmod(int32_t n, int32_t d);
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

/* n / d, and n % d in *rem (no '/' or '%' here: those would call these very functions). */
static uint32_t udivmod(uint32_t n, uint32_t d, uint32_t *rem)
{
    uint32_t q = 0, bit;
    if (d == 0 || n < d) {
        *rem = n;
        return 0;
    }
    for (bit = 1; d <= n >> 1; bit <<= 1) /* d up to the quotient's top bit (no overflow: d <= n / 2) */
        d <<= 1;
    do {
        if (n >= d) {
            n -= d;
            q |= bit;
        }
        d >>= 1;
        bit >>= 1;
    } while (bit);
    *rem = n;
    return q;
}

uint32_t __udivsi3(uint32_t n, uint32_t d)
{
    uint32_t r;
    return udivmod(n, d, &r);
}

uint32_t __aeabi_uidiv(uint32_t n, uint32_t d) __attribute__((alias("__udivsi3")));

/* {quotient in r0, remainder in r1}: the run-time ABI's pair is a 64-bit return value's two halves */
uint64_t __aeabi_uidivmod(uint32_t n, uint32_t d)
{
    uint32_t r, q;
    if (n < d) /* the board's most frequent case: an index modulo a small count */
        return (uint64_t)n << 32;
    q = udivmod(n, d, &r);
    return (uint64_t)r << 32 | q;
}

static int32_t idivmod(int32_t n, int32_t d, int32_t *rem)
{
    uint32_t un = n < 0 ? 0u - (uint32_t)n : (uint32_t)n, ud = d < 0 ? 0u - (uint32_t)d : (uint32_t)d, ur;
    uint32_t q = udivmod(un, ud, &ur);
    *rem = (int32_t)(n < 0 ? 0u - ur : ur);
    return (int32_t)((n < 0) != (d < 0) ? 0u - q : q);
}

int32_t __divsi3(int32_t n, int32_t d)
{
    int32_t r;
    return idivmod(n, d, &r);
}

int32_t __aeabi_idiv(int32_t n, int32_t d) __attribute__((alias("__divsi3")));

int64_t __aeabi_idivmod(int32_t n, int32_t d)
{
    int32_t r, q = idivmod(n, d, &r);
    return (int64_t)((uint64_t)(uint32_t)r << 32 | (uint32_t)q);
}

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
