/* Hand-written held step of a particle sliding inside the sphere |q| = r under gravity (m = 1, g along -z): the
 * trapezoidal RATTLE step of MATH.md *Sustained contact* on one row, written for this row alone, as a rotation
 * (the circle's of vcigen.held_circle carried to three coordinates). The practical speed limit of
 * bench/held_curved.py's `sphere` scene: it does what the generated <model>_held_closed_loop does a step (one
 * sqrt, the projection, E_d, the normal force and its lift-off test, the residual and finiteness tests) and
 * stores the same output (q, p, E_d, the impulse over h per step), in the fewest operations we could write.
 *   cc -std=c99 -O2 -Wall -Wextra -Werror -fPIC -shared -o libhw_sphere_rot.so sphere_rot.c -lm
 *
 * With w the tangential part of the free velocity v0 = p - (0, 0, g h/2) at q and c = (0, 0, -g h):
 *   q1 = s q + h w,   s = sqrt(arg),   arg = (r^2 - h^2 |w|^2) / |q|^2   (|q1| = r: the small root),
 *   p1 = p+ - (p+ . q1) q1 / r^2,   p+ = v - (0, 0, g h/2),   v = (q1 - q) / h,
 *   the next w = T1 (s w - h |w|^2 q / r^2 + c)   (T1 the projection onto the tangent at q1: the rotation keeps
 *   |w|, so |w'|^2 = a0 + a1 s once s^2 = arg is taken off: a scalar carried beside w),
 *   the next arg = (2 - |q1|^2 / r^2) (r^2 - h^2 |w'|^2) / r^2 to O((|q1|^2 / r^2 - 1)^2), = A + B s:
 * the chain from one sqrt to the next is one multiply-add, as in the circle's loop. Returns the steps taken (a
 * step that fails a test ends the run). */
#include <math.h>

long hw_sphere_run(const double *q0, const double *p0, double h, double r, double g, long n, double *Q,
    double *P, double *E, double *F)
{
    double x = q0[0], y = q0[1], z = q0[2], px = p0[0], py = p0[1], pz = p0[2];
    const double k0 = -0.5 * g * h, cz = -g * h, h2 = h * h, ih = 1.0 / h, r2 = r * r, ir2 = 1.0 / r2;
    const double tol = 1e-10, hr2 = h2 * ir2;
    /* w at the entry: the tangential part of v0 at q */
    const double qq0 = x * x + y * y + z * z, dn = (px * x + py * y + (pz + k0) * z) / qq0;
    double wx = px - dn * x, wy = py - dn * y, wz = pz + k0 - dn * z;
    double ww = wx * wx + wy * wy + wz * wz, qq = qq0 * ir2, arg = (1.0 - hr2 * ww) / qq;
    long k;
    for (k = 0; k < n; ++k) {
        const double s = sqrt(arg);
        const double x1 = s * x + h * wx, y1 = s * y + h * wy, z1 = s * z + h * wz;
        /* the next w = W0 + W1 s and |w'|^2 = a0 + a1 s (cq = c . q / r^2, cw = c . w), off the chain */
        const double cq = cz * z * ir2, cw = cz * wz, hw = h * ww * ir2, acq = arg * cq;
        const double w0x = -(hw + acq) * x - hr2 * cw * wx, w1x = wx - h * (cq * wx + cw * x * ir2);
        const double w0y = -(hw + acq) * y - hr2 * cw * wy, w1y = wy - h * (cq * wy + cw * y * ir2);
        const double w0z = -(hw + acq) * z - hr2 * cw * wz + cz, w1z = wz - h * (cq * wz + cw * z * ir2);
        const double a0 = ww + cz * cz - acq * cz * z - hr2 * cw * cw - 2.0 * hw * cz * z;
        const double a1 = 2.0 * cw * (1.0 - h * cq);
        const double qw = (x * wx + y * wy + z * wz) * ir2;
        const double an = 2.0 - arg * qq - hr2 * (ww + a0), bn = -2.0 * h * qw - hr2 * a1;
        /* the end: p+, its projection, E_d, the force and the residual */
        const double vx = (x1 - x) * ih, vy = (y1 - y) * ih, vz = (z1 - z) * ih, ppz = vz + k0;
        const double pn = (vx * x1 + vy * y1 + ppz * z1) * ir2;
        const double p1x = vx - pn * x1, p1y = vy - pn * y1, p1z = ppz - pn * z1;
        const double e = 0.5 * (vx * vx + vy * vy + vz * vz) + g * z - k0 * vz;
        const double force = (p1x * p1x + p1y * p1y + p1z * p1z - g * z1) / r;
        const double res = (x1 * x1 + y1 * y1 + z1 * z1 - r2) * (-0.5 / r);
        const double tot = e + force + x1 + y1 + z1 + p1x + p1y + p1z;
        if (!(arg >= 0.0) | !(fabs(res) <= tol) | (force < -1e-12 * (1.0 + fabs(force))) | !isfinite(tot)) {
            break;
        }
        /* (Lam + Lam') / h from the momentum change J = p1 - p0 - c along q0 + q1 */
        F[k] = -((p1x - px) * (x + x1) + (p1y - py) * (y + y1) + (p1z - pz - cz) * (z + z1)) / (r * (1.0 + s) * h);
        wx = w0x + w1x * s;
        wy = w0y + w1y * s;
        wz = w0z + w1z * s;
        ww = a0 + a1 * s;
        arg = an + bn * s;
        qq = (x1 * x1 + y1 * y1 + z1 * z1) * ir2;
        x = x1, y = y1, z = z1, px = p1x, py = p1y, pz = p1z;
        Q[3 * k] = x, Q[3 * k + 1] = y, Q[3 * k + 2] = z;
        P[3 * k] = px, P[3 * k + 1] = py, P[3 * k + 2] = pz;
        E[k] = e;
    }
    return k;
}
