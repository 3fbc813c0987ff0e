/* Hand-written chain pendulum (CHAIN_N point masses on rigid rods, angles from the downward vertical):
 * the trapezoid (71) and midpoint (57) variational steps with Newton on the segment velocity v and the
 * hand-derived Jacobian, the mass-matrix terms at q_k carried over from the end of the step before,
 * phi = x_w - sum l_i sin q_i (the wall) at each step end. The practical speed limit of bench/c_speed.py
 * for models without explicit structure: it stores q, p and E_d per step, as the generated code does.
 *   cc -std=c99 -O2 -DCHAIN_N=2 -fPIC -shared -o libhw_chain2.so chain.c -lm
 *
 * With M_ij = c_ij cos(q_i - q_j), c_ij = l_i l_j sum_{k >= max(i,j)} m_k, V = -sum_i g l_i mu_i cos q_i
 * (mu_i = sum_{k >= i} m_k), L = w^T M w / 2 - V:
 *   G_i(q, w) = dL/dq_i = -sum_k c_ik sin(q_i - q_k) w_i w_k - g l_i mu_i sin q_i,
 *   B_jl(q, w) = [dM/dq_l w]_j, Gw = dG/dw, Gq = dG/dq.
 * Trapezoid: F(v) = (M0 + M1) v / 2 - h/2 G(q0, v) - p0, p1 = (M0 + M1) v / 2 + h/2 G(q1, v),
 *            E_d = v^T (M0 + M1) v / 4 + (V0 + V1) / 2.
 * Midpoint:  F(v) = Mm v - h/2 G(qm, v) - p0, p1 = Mm v + h/2 G(qm, v), E_d = v^T Mm v / 2 + V(qm). */
#include <math.h>

#ifndef CHAIN_N
#define CHAIN_N 2
#endif
#define N CHAIN_N

typedef struct {
    double s[N], c[N];         /* sin q_i, cos q_i */
    double sd[N][N], cd[N][N]; /* sin, cos of q_i - q_j */
} trig_t;

static inline void trig_all(const double *q, trig_t *t)
{
    int i, j;
    for (i = 0; i < N; ++i) {
        t->s[i] = sin(q[i]);
        t->c[i] = cos(q[i]);
        t->sd[i][i] = 0.0;
        t->cd[i][i] = 1.0;
    }
    for (i = 0; i < N; ++i) {
        for (j = i + 1; j < N; ++j) { /* from the products: no more sin/cos calls */
            t->sd[i][j] = t->s[i] * t->c[j] - t->c[i] * t->s[j];
            t->cd[i][j] = t->c[i] * t->c[j] + t->s[i] * t->s[j];
            t->sd[j][i] = -t->sd[i][j];
            t->cd[j][i] = t->cd[i][j];
        }
    }
}

/* Solve a x = b (N x N, a destroyed) by Gaussian elimination without pivoting (M is SPD-dominated). */
static inline void solve(double a[N][N], double *b)
{
    int i, j, k;
    for (k = 0; k < N; ++k) {
        for (i = k + 1; i < N; ++i) {
            const double f = a[i][k] / a[k][k];
            for (j = k + 1; j < N; ++j) {
                a[i][j] -= f * a[k][j];
            }
            b[i] -= f * b[k];
        }
    }
    for (i = N - 1; i >= 0; --i) {
        for (j = i + 1; j < N; ++j) {
            b[i] -= a[i][j] * b[j];
        }
        b[i] /= a[i][i];
    }
}

static inline double norm_inf(const double *r)
{
    double big = 0.0;
    int i;
    for (i = 0; i < N; ++i) {
        big = fabs(r[i]) > big ? fabs(r[i]) : big;
    }
    return big;
}

typedef struct {
    double c[N][N], gl[N], l[N], xw; /* c_ij, g l_i mu_i, l_i, wall */
} chain_t;

static void setup(chain_t *ch, const double *m, const double *l, double g, double xw)
{
    int i, j, k;
    for (i = 0; i < N; ++i) {
        double mu = 0.0;
        for (k = i; k < N; ++k) {
            mu += m[k];
        }
        ch->gl[i] = g * l[i] * mu;
        ch->l[i] = l[i];
        for (j = 0; j < N; ++j) {
            double mm = 0.0;
            for (k = (i > j ? i : j); k < N; ++k) {
                mm += m[k];
            }
            ch->c[i][j] = l[i] * l[j] * mm;
        }
    }
    ch->xw = xw;
}

static inline double potential(const chain_t *ch, const trig_t *t)
{
    double v = 0.0;
    int i;
    for (i = 0; i < N; ++i) {
        v -= ch->gl[i] * t->c[i];
    }
    return v;
}

static inline double wall(const chain_t *ch, const trig_t *t)
{
    double x = 0.0;
    int i;
    for (i = 0; i < N; ++i) {
        x += ch->l[i] * t->s[i];
    }
    return ch->xw - x;
}

/* M(q) w and G(q, w). */
static inline void mass_times(const chain_t *ch, const trig_t *t, const double *w, double *mw)
{
    int i, k;
    for (i = 0; i < N; ++i) {
        mw[i] = 0.0;
        for (k = 0; k < N; ++k) {
            mw[i] += ch->c[i][k] * t->cd[i][k] * w[k];
        }
    }
}

static inline void force(const chain_t *ch, const trig_t *t, const double *w, double *gq)
{
    int i, k;
    for (i = 0; i < N; ++i) {
        double a = 0.0;
        for (k = 0; k < N; ++k) {
            a += ch->c[i][k] * t->sd[i][k] * w[k];
        }
        gq[i] = -a * w[i] - ch->gl[i] * t->s[i];
    }
}

/* Newton stops at |F|_inf <= TOL or |dv|_inf <= TOL_STEP (the generated code's abstol, abstol_step: the
 * residual's round-off can stay above TOL) or after MAX_IT steps. */
#define TOL 1e-13
#define TOL_STEP 1e-15
#define MAX_IT 40

long hw_chain_trapezoid(const double *m, const double *l, double g, double xw, const double *q0, const double *v0,
    double h, long n_steps, double *Q, double *P, double *E)
{
    chain_t ch;
    trig_t t0, t1;
    double q[N], p[N], v[N], m0v[N], g0[N], e0;
    long k;
    int i, j, it;
    setup(&ch, m, l, g, xw);
    for (i = 0; i < N; ++i) {
        q[i] = q0[i];
        v[i] = v0[i];
    }
    trig_all(q, &t0);
    mass_times(&ch, &t0, v, p);
    e0 = potential(&ch, &t0);
    for (k = 0; k < n_steps; ++k) {
        double q1[N], f[N], jac[N][N], m1v[N], g1[N], e1;
        for (it = 0; it < MAX_IT; ++it) { /* Newton on v: trig at q1 = q + h v each iteration */
            double sd1, cd1, a;
            for (i = 0; i < N; ++i) {
                q1[i] = q[i] + h * v[i];
            }
            for (i = 0; i < N; ++i) { /* only the differences enter M(q1): sin/cos of q1_i - q1_j */
                t1.sd[i][i] = 0.0;
                t1.cd[i][i] = 1.0;
                for (j = i + 1; j < N; ++j) {
                    const double dq = q1[i] - q1[j];
                    sd1 = sin(dq);
                    cd1 = cos(dq);
                    t1.sd[i][j] = sd1;
                    t1.sd[j][i] = -sd1;
                    t1.cd[i][j] = t1.cd[j][i] = cd1;
                }
            }
            mass_times(&ch, &t0, v, m0v);
            mass_times(&ch, &t1, v, m1v);
            force(&ch, &t0, v, g0);
            for (i = 0; i < N; ++i) {
                f[i] = 0.5 * (m0v[i] + m1v[i]) - 0.5 * h * g0[i] - p[i];
            }
            if (norm_inf(f) <= TOL) {
                break;
            }
            /* J = (M0 + M1)/2 + h/2 B(q1, v) - h/2 Gw(q0, v) */
            for (i = 0; i < N; ++i) {
                double b1 = 0.0, b0 = 0.0;
                for (j = 0; j < N; ++j) {
                    a = ch.c[i][j];
                    jac[i][j] = 0.5 * a * (t0.cd[i][j] + t1.cd[i][j])
                        + 0.5 * h * (a * t1.sd[i][j] * v[j] + a * t0.sd[i][j] * v[i]);
                    b1 += a * t1.sd[i][j] * v[j];
                    b0 += a * t0.sd[i][j] * v[j];
                }
                jac[i][i] += 0.5 * h * (b0 - b1);
            }
            solve(jac, f);
            for (i = 0; i < N; ++i) {
                v[i] -= f[i];
            }
            if (norm_inf(f) <= TOL_STEP) {
                break;
            }
        }
        for (i = 0; i < N; ++i) {
            q1[i] = q[i] + h * v[i];
        }
        trig_all(q1, &t1); /* the step end: p1, E_d, phi; carried over as the next step's q_k terms */
        mass_times(&ch, &t0, v, m0v);
        mass_times(&ch, &t1, v, m1v);
        force(&ch, &t1, v, g1);
        e1 = potential(&ch, &t1);
        E[k] = 0.0;
        for (i = 0; i < N; ++i) {
            E[k] += 0.25 * v[i] * (m0v[i] + m1v[i]);
            p[i] = 0.5 * (m0v[i] + m1v[i]) + 0.5 * h * g1[i];
            q[i] = q1[i];
            Q[k * N + i] = q[i];
            P[k * N + i] = p[i];
        }
        E[k] += 0.5 * (e0 + e1);
        if (!(it < MAX_IT) || !(wall(&ch, &t1) >= 0.0)) { /* no root, or the wall is crossed: stop */
            return k;
        }
        t0 = t1;
        e0 = e1;
    }
    return k;
}

long hw_chain_midpoint(const double *m, const double *l, double g, double xw, const double *q0, const double *v0,
    double h, long n_steps, double *Q, double *P, double *E)
{
    chain_t ch;
    trig_t tm, t1;
    double q[N], p[N], v[N], mv[N], gm[N];
    long k;
    int i, j, it;
    setup(&ch, m, l, g, xw);
    for (i = 0; i < N; ++i) {
        q[i] = q0[i];
        v[i] = v0[i];
    }
    trig_all(q, &tm);
    mass_times(&ch, &tm, v, p);
    for (k = 0; k < n_steps; ++k) {
        double qm[N], q1[N], f[N], jac[N][N];
        for (it = 0; it < MAX_IT; ++it) { /* Newton on v: trig at qm = q + h v / 2 each iteration */
            for (i = 0; i < N; ++i) {
                qm[i] = q[i] + 0.5 * h * v[i];
            }
            trig_all(qm, &tm);
            mass_times(&ch, &tm, v, mv);
            force(&ch, &tm, v, gm);
            for (i = 0; i < N; ++i) {
                f[i] = mv[i] - 0.5 * h * gm[i] - p[i];
            }
            if (norm_inf(f) <= TOL) {
                break;
            }
            /* J = Mm + h/2 B(qm, v) - h/2 Gw(qm, v) - h^2/4 Gq(qm, v) */
            for (i = 0; i < N; ++i) {
                double bc = 0.0;
                for (j = 0; j < N; ++j) {
                    const double a = ch.c[i][j];
                    jac[i][j] = a * tm.cd[i][j] + 0.5 * h * (a * tm.sd[i][j] * v[j] + a * tm.sd[i][j] * v[i])
                        - 0.25 * h * h * a * tm.cd[i][j] * v[i] * v[j];
                    bc += a * tm.cd[i][j] * v[j];
                }
                jac[i][i] += 0.25 * h * h * (v[i] * bc + ch.gl[i] * tm.c[i]);
            }
            solve(jac, f);
            for (i = 0; i < N; ++i) {
                v[i] -= f[i];
            }
            if (norm_inf(f) <= TOL_STEP) {
                break;
            }
        }
        for (i = 0; i < N; ++i) {
            qm[i] = q[i] + 0.5 * h * v[i];
            q1[i] = q[i] + h * v[i];
        }
        trig_all(qm, &tm);
        mass_times(&ch, &tm, v, mv);
        force(&ch, &tm, v, gm);
        E[k] = potential(&ch, &tm);
        for (i = 0; i < N; ++i) {
            E[k] += 0.5 * v[i] * mv[i];
            p[i] = mv[i] + 0.5 * h * gm[i];
            q[i] = q1[i];
            Q[k * N + i] = q[i];
            P[k * N + i] = p[i];
        }
        for (i = 0; i < N; ++i) { /* phi at the step end */
            t1.s[i] = sin(q1[i]);
        }
        if (!(it < MAX_IT) || !(wall(&ch, &t1) >= 0.0)) {
            return k;
        }
    }
    return k;
}
