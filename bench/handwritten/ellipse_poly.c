/* Hand-written held step of bench/handwritten/ellipse.c (the same row, step, outputs and tests), with the next
 * step's quadratic along its line formed as polynomials in this step's root (stop 34's experiment on item 8):
 * a' = al + 2 h Lam G(q0) and G(q1) = S a + h Lam S G(q0) (S = diag(1/4, 1)) are affine in Lam, so the next
 * B = a'.S G(q1), A = G(q1).S G(q1) and C = a'.S a' - r^2 are quadratics in Lam whose coefficients come from the
 * step's start (off the state's chain) and D = B^2 - A C follows Lam by five operations (about eight in
 * ellipse.c: q1, G(q1), a', then B, A, C). bench/held_curved.py times it beside ellipse.c and checks it against
 * the generated run (q, p to 1e-9); it is not the generated code.
 *   cc -std=c99 -O2 -Wall -Wextra -Werror -fPIC -shared -o libhw_ellipse_poly.so ellipse_poly.c -lm */
#include <math.h>

long hw_ellipse_run(const double *q0, const double *p0, double h, double r, double g, long n, double *Q,
    double *P, double *E, double *F)
{
    double x = q0[0], y = q0[1], px = p0[0], py = p0[1], lp = 0.0;
    const double hg2 = 0.5 * g * h, r2 = r * r, tol = 1e-10, h2 = h * h;
    double gx = 0.25 * x, gy = y;
    double v0x = px, v0y = py - hg2, ax = x + h * v0x, ay = y + h * v0y;
    /* the first step's B, A, C directly; each later step's as quadratics in the Lam before */
    double ex = 0.25 * gx, ey = gy, A = gx * ex + gy * ey;
    double bb = ax * ex + ay * ey, cc = 0.25 * ax * ax + ay * ay - r2;
    double d = bb * bb - A * cc, ia = 1.0 / (h * A);
    long k;
    for (k = 0; k < n; ++k) {
        double lam, vx, vy, x1, y1, ppx, ppy, gx1, gy1, iw1, lam1, p1x, p1y, force, e;
        if (!(bb > 0.0) || !(d >= 0.0)) {
            break;
        }
        lam = (sqrt(d) - bb) * ia;
        {
            /* the next step's B, A, C as quadratics in Lam, their coefficients from this step's start */
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
            const double nd = nb * nb - nA * nc;
            x1 = ax + lam * h * gx;
            y1 = ay + lam * h * gy;
            vx = v0x + lam * gx;
            vy = v0y + lam * gy;
            e = 0.5 * (vx * vx + vy * vy) + g * (y + 0.5 * h * vy);
            ppx = vx;
            ppy = vy - hg2;
            gx1 = 0.25 * x1;
            gy1 = y1;
            iw1 = 1.0 / (gx1 * gx1 + gy1 * gy1);
            lam1 = -(gx1 * ppx + gy1 * ppy) * iw1;
            p1x = ppx + lam1 * gx1;
            p1y = ppy + lam1 * gy1;
            force = (g * gy1 - (0.25 * p1x * p1x + p1y * p1y)) * iw1;
            if (!(fabs(0.25 * x1 * x1 + y1 * y1 - r2) <= tol * (1.0 + fabs(px) + fabs(py)))) {
                break;
            }
            if (force > 1e-12 * (1.0 + fabs(force)) || !isfinite(e + force + x1 + y1 + p1x + p1y)) {
                break;
            }
            Q[2 * k] = x1;
            Q[2 * k + 1] = y1;
            P[2 * k] = p1x;
            P[2 * k + 1] = p1y;
            E[k] = e;
            F[k] = (lam - lp + lam1) / h;
            x = x1;
            y = y1;
            px = p1x;
            py = p1y;
            lp = lam1;
            ax = alx + lam * 2.0 * h * gx;
            ay = aly + lam * 2.0 * h * gy;
            v0x = ppx;
            v0y = ppy - hg2;
            gx = gx1;
            gy = gy1;
            ex = 0.25 * gx;
            ey = gy;
            A = nA;
            bb = nb;
            d = nd;
            ia = 1.0 / (h * nA);
        }
    }
    return k;
}
