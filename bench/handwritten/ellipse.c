/* Hand-written held step of a particle sliding inside the ellipse x^2/4 + y^2 = r^2 under gravity (m = 1):
 * the trapezoidal RATTLE step of MATH.md *Sustained contact* on one row, written for this row alone. The
 * practical speed limit of bench/held_curved.py's `ellipse` scene: it does what the generated
 * <model>_held_closed_loop does a step (the root of the row's quadratic along the line by one sqrt, the
 * projection, E_d, the normal force and its lift-off test, the residual and finiteness tests) and stores the
 * same output (q, p, E_d, force per step), in the fewest operations we could write.
 *   cc -std=c99 -O2 -Wall -Wextra -Werror -fPIC -shared -o libhw_ellipse.so ellipse.c -lm
 *
 * With F = x^2/4 + y^2 - r^2 and G(q) = grad F / 2 = (x/4, y), V = g y:
 *   v = p0 - (0, g h/2) + G(q0) Lam,   q1 = q0 + h v,   F(q1) = 0   (a quadratic in Lam: its small root),
 *   p+ = v - (0, g h/2),   p1 = p+ + G(q1) Lam',   G(q1) . p1 = 0,
 *   E_d = |v|^2 / 2 + g (y0 + y1) / 2,   force: lambda G(q1) . G(q1) = -(G(q1) . (0, -g) + p1 . Hess(F/2) p1).
 * The line starts from the previous step's p+ (its projection is absorbed by the root), as the generated loop
 * does; 1 / (h A) at q is formed at the end of the step before (off the state's chain, as the generated
 * held_root_dir's); beyond the generated loop, the next line's start a' = q1 + h v0' is formed as
 * al + Lam be, al and be off the chain, one multiply-add after the root. Returns the steps taken (a step that fails
 * a test ends the run). */
#include <math.h>

long hw_ellipse_run(const double *q0, const double *p0, double h, double r, double g, long n, double *Q,
    double *P, double *E, double *F)
{
    double x = q0[0], y = q0[1], px = p0[0], py = p0[1], lp = 0.0;
    const double hg2 = 0.5 * g * h, r2 = r * r, tol = 1e-10;
    double gx = 0.25 * x, gy = y, ia = 1.0 / (h * (0.25 * gx * gx + gy * gy)); /* 1 / (h A) at q */
    double v0x = px, v0y = py - hg2, ax = x + h * v0x, ay = y + h * v0y;   /* the free velocity, the line's start */
    long k;
    for (k = 0; k < n; ++k) {
        /* F(a + h Lam G) = h^2 A Lam^2 + 2 h B Lam + C, A = G . diag(1/4, 1) G: Lam = (sqrt(D) - B) / (h A) */
        const double ex = 0.25 * gx, ey = gy;
        const double b = ax * ex + ay * ey, c = 0.25 * ax * ax + ay * ay - r2, d = b * b - (gx * ex + gy * ey) * c;
        const double alx = ax + h * v0x, aly = ay + h * (v0y - 2.0 * hg2), hgx = h * gx, hgy = h * gy;
        double lam, vx, vy, x1, y1, ppx, ppy, gx1, gy1, iw1, lam1, p1x, p1y, force, e;
        if (!(b > 0.0) || !(d >= 0.0)) {
            break;
        }
        lam = (sqrt(d) - b) * ia; /* the small root */
        x1 = ax + lam * hgx;
        y1 = ay + lam * hgy;
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
        force = (g * gy1 - (0.25 * p1x * p1x + p1y * p1y)) * iw1; /* > 0 pulls off the wall: a lift-off */
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
        ax = alx + lam * (hgx + hgx); /* a' = q1 + h v0' = (a + h v0 - h^2 g) + 2 h Lam G */
        ay = aly + lam * (hgy + hgy);
        v0x = ppx;
        v0y = ppy - hg2;
        gx = gx1;
        gy = gy1;
        ia = 1.0 / (h * (0.25 * gx1 * gx1 + gy1 * gy1));
    }
    return k;
}
