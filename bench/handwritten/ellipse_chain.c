/* The state's chain of bench/handwritten/ellipse_poly.c alone (stop 39): the same held steps on the same row,
 * each step's root, q1 and the momentum p+ before its projection, stored; no projection, no force, no E_d and no
 * tests but the root's own (B > 0, D >= 0). A floor for item 8 on this row: what a held step costs that keeps
 * nothing but the recurrence from one root to the next. bench/held_curved.py times it beside ellipse_poly.c and
 * checks its Q against the generated run (to 1e-9; its P is p+, not p, and E, F are not written).
 *   cc -std=c99 -O2 -Wall -Wextra -Werror -fPIC -shared -o libhw_ellipse_chain.so ellipse_chain.c -lm */
#include <math.h>

long hw_ellipse_run(const double *q0, const double *p0, double h, double r, double g, long n, double *Q,
    double *P, double *E, double *F)
{
    double x = q0[0], y = q0[1], px = p0[0], py = p0[1];
    const double hg2 = 0.5 * g * h, r2 = r * r, h2 = h * h;
    double gx = 0.25 * x, gy = y;
    double v0x = px, v0y = py - hg2, ax = x + h * v0x, ay = y + h * v0y;
    double ex = 0.25 * gx, ey = gy, A = gx * ex + gy * ey;
    double bb = ax * ex + ay * ey, cc = 0.25 * ax * ax + ay * ay - r2;
    double d = bb * bb - A * cc, ia = 1.0 / (h * A);
    long k;
    (void)E;
    (void)F;
    for (k = 0; k < n; ++k) {
        double lam, vx, vy, x1, y1;
        if (!(bb > 0.0) || !(d >= 0.0)) {
            break;
        }
        lam = (sqrt(d) - bb) * ia;
        {
            const double alx = ax + h * v0x, aly = ay + h * (v0y - 2.0 * hg2);
            const double ux = 0.25 * ax, uy = ay, sux = 0.25 * ux, suy = uy, sex = 0.25 * ex, sey = ey;
            const double b0 = alx * sux + aly * suy;
            const double b1 = h * (alx * sex + aly * sey) + 2.0 * h * (gx * sux + gy * suy);
            const double b2 = 2.0 * h2 * (ex * ex + ey * ey);
            const double a0 = ux * sux + uy * suy, a1 = 2.0 * h * (ux * sex + uy * sey), a2 = h2 * (ex * sex + ey * sey);
            const double c0 = 0.25 * alx * alx + aly * aly - r2, c1 = 4.0 * h * (alx * ex + aly * ey), c2 = 4.0 * h2 * A;
            const double l2 = lam * lam;
            const double nb = (b0 + b1 * lam) + b2 * l2;
            const double nA = (a0 + a1 * lam) + a2 * l2;
            const double nc = (c0 + c1 * lam) + c2 * l2;
            x1 = ax + lam * h * gx;
            y1 = ay + lam * h * gy;
            vx = v0x + lam * gx;
            vy = v0y + lam * gy;
            Q[2 * k] = x1;
            Q[2 * k + 1] = y1;
            P[2 * k] = vx;
            P[2 * k + 1] = vy - hg2;
            ax = alx + lam * 2.0 * h * gx;
            ay = aly + lam * 2.0 * h * gy;
            v0x = vx;
            v0y = vy - 2.0 * hg2;
            gx = 0.25 * x1;
            gy = y1;
            ex = 0.25 * gx;
            ey = gy;
            A = nA;
            bb = nb;
            d = nb * nb - nA * nc;
            ia = 1.0 / (h * nA);
        }
    }
    return k;
}
