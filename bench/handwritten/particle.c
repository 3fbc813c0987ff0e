/* Hand-written particle on a floor: Stormer-Verlet (the trapezoidal VCI of this Lagrangian) with an
 * analytic impact time and an elastic reflection. The practical speed limit of bench/c_speed.py:
 * it stores the same output as the generated code (q, p, energy per step; t and impulse per impact).
 *   cc -std=c99 -O2 -fPIC -shared -o libhw_particle.so particle.c -lm */
#include <math.h>

long hw_particle_run(const double *q0, const double *v0, double h, double m, double g, long n_steps,
    long max_impacts, double *Q, double *P, double *E, double *impacts, long *n_impacts)
{
    double x = q0[0], y = q0[1], px = m * v0[0], py = m * v0[1];
    long k, n_imp = 0;
    for (k = 0; k < n_steps && n_imp < max_impacts; ++k) {
        const double vx = px / m;
        double vy = py / m - 0.5 * g * h; /* segment velocity of the step */
        double y1 = y + h * vy;
        double e = 0.5 * m * (vx * vx + vy * vy) + m * g * (y + 0.5 * h * vy); /* E_d (72) */
        if (y1 < 0.0) { /* y + s py/m - g s^2/2 = 0: the earliest positive root */
            const double a = 0.5 * g, b = -py / m, c = -y;
            const double s = (-b + sqrt(b * b - 4.0 * a * c)) / (2.0 * a);
            const double vin = py / m - g * s, r = h - s;
            impacts[2 * n_imp] = (double)k * h + s;
            impacts[2 * n_imp + 1] = -2.0 * m * vin;
            ++n_imp;
            y1 = r * (-vin) - 0.5 * g * r * r;
            py = -m * vin - m * g * r;
        } else {
            py -= m * g * h;
        }
        x += h * vx;
        y = y1;
        Q[2 * k] = x;
        Q[2 * k + 1] = y;
        P[2 * k] = px;
        P[2 * k + 1] = py;
        E[k] = e;
    }
    *n_impacts = n_imp;
    return k;
}
