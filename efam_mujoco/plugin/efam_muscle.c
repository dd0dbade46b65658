// efam.muscle: the force-balance model of a fluidic artificial muscle (Garbulinski et al. 2021,
// Eq. 2) as a MuJoCo actuator plugin.
//
// The Python model (efam_mujoco/muscle.py, stress.py) is the reference. Every expression below
// is evaluated in the same order as there, with the same constants, so the two agree to the last
// few bits: that is what lets a test hold them to 1e-9. (An instance that drives several
// actuators computes them as one vectorised batch, see tension_batch; there e^3 is e*e*e and exp
// is a polynomial of our own, each within two roundings of libm.) Where Python squares a float with `**2`
// we call libm pow() too (not x*x), and the admissible length range is found with the same
// Brent iteration scipy.optimize.brentq performs, because at the ends of that range the force
// depends on the last bit of the bound.
//
// Sign: actuator_force = -tension (positive = the muscle pushes its ends apart).
// Control: gauge pressure in Pa: ctrl (dyntype none) or the actuator's activation (a filtered
// pressure, e.g. dyntype="filterexact" dynprm="tau" actdim="1").
// Length: actuator_length (tendon or joint length, m).

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#if defined(_WIN32)
#define EFAM_EXPORT __declspec(dllexport)
#else
#define EFAM_EXPORT __attribute__((visibility("default")))
#endif

#define PLUGIN_NAME "efam.muscle"

// ----------------------------------------------------------------- errors during init
// mj_initPlugin frees the mjData it is making when init returns -1, but an mju_error raised
// inside init never returns there (MuJoCo's error handlers longjmp, throw or exit), so that
// mjData (buffer, arena, struct: ~20 KB touched per rejected model) and the instances already
// initialised would leak on every rejected config. Every error in this file goes through
// efam_fail: while an init runs on this thread, it first frees what mj_makeData/mj_copyData
// allocated for the unborn mjData (nobody else can reach it), as mj_initPlugin's own failure
// path does, then raises the error with its full message (the config key named).
#if defined(_MSC_VER)
#define EFAM_THREAD_LOCAL __declspec(thread)
#else
#define EFAM_THREAD_LOCAL _Thread_local
#endif

static EFAM_THREAD_LOCAL mjData* init_data;  // the mjData an init on this thread is filling
static EFAM_THREAD_LOCAL int init_instance;

static void release_unborn_data(mjData* d, int instance) {
  for (int j = 0; j < instance; j++) {  // instances initialised before this one
    const mjpPlugin* plugin = mjp_getPluginAtSlot(d->plugin[j]);
    if (plugin && plugin->destroy && d->plugin_data[j]) {
      plugin->destroy(d, j);
    }
  }
  mju_free(d->buffer);
  mju_free(d->arena);
  mju_free(d);
}

static void efam_fail(const char* fmt, ...) {
  char message[1024];
  va_list args;
  va_start(args, fmt);
  vsnprintf(message, sizeof(message), fmt, args);
  va_end(args);
  mjData* d = init_data;
  init_data = NULL;
  if (d) {
    release_unborn_data(d, init_instance);
  }
  (mju_error)("%s", message);
  if (d) {  // a handler that returns breaks MuJoCo's contract; d is gone, so stop here
    fprintf(stderr, "%s\n", message);
    abort();
  }
}
#define mju_error(...) efam_fail(__VA_ARGS__)
#define DEFAULT_LOCK_STIFFNESS 2.0e4
#define STRAIN_SAMPLES 2001  // Muscle.strain_range samples the admissible lengths this densely
#define BRENT_XTOL 1e-15     // the tolerances muscle._admissible_lengths gives brentq
#define BRENT_RTOL 1e-15
#define BRENT_MAXITER 100
#define MAX_PRESSURE_SENSORS 8  // pressure sensors one instance may feed

// ------------------------------------------------------------------------------ stress laws

typedef enum { LAW_LINEAR, LAW_POLYNOMIAL, LAW_EXP_DECAY, LAW_EXPONENT, LAW_SIGMOID, LAW_ARCCOT, NLAW } Law;

typedef struct {
  double lo, hi;
  int lo_open, hi_open;
} Bound;

typedef struct {
  const char* name;
  int ncoef;
  const char* keys[4];
  Bound bounds[4];
} LawSpec;

// Hard bounds exactly as stress.LAWS (paper Table 5).
#define E1_BOUND {0.0, INFINITY, 1, 0}
#define E2_BOUND {0.0, INFINITY, 0, 0}
#define FREE_BOUND {-INFINITY, INFINITY, 0, 0}
#define NONNEG_BOUND {0.0, INFINITY, 0, 0}
#define POSITIVE_BOUND {0.0, INFINITY, 1, 0}

static const LawSpec kLaws[NLAW] = {
    {"linear", 2, {"E1_Pa", "E2"}, {E1_BOUND, E2_BOUND}},
    {"polynomial", 4, {"E1_Pa", "E2", "E3_Pa", "E4_Pa"}, {E1_BOUND, E2_BOUND, FREE_BOUND, FREE_BOUND}},
    {"exponential_decay",
     4,
     {"E1_Pa", "E2", "E3_Pa", "E4"},
     {E1_BOUND, E2_BOUND, NONNEG_BOUND, POSITIVE_BOUND}},
    {"exponent", 4, {"E1_Pa", "E2", "E3", "E4"}, {E1_BOUND, E2_BOUND, {0.0, 1.0, 1, 1}, {1.0, INFINITY, 1, 0}}},
    {"sigmoid", 4, {"E1_Pa", "E2", "E3_Pa", "E4"}, {E1_BOUND, E2_BOUND, NONNEG_BOUND, POSITIVE_BOUND}},
    {"arccot", 4, {"E1_Pa", "E2", "E3_Pa", "E4"}, {E1_BOUND, E2_BOUND, NONNEG_BOUND, POSITIVE_BOUND}},
};

// Every config key the plugin accepts (MuJoCo rejects any other key at compile time).
static const char* const kAttributes[] = {
    "rest_length_m", "rest_diameter_m", "theta_rest_deg", "bladder_volume_m3", "deadband_Pa",
    "law",           "tension_only",    "lock_stiffness_N_per_m",
    "E1_Pa",         "E2",              "E3_Pa",          "E3",          "E4_Pa", "E4",
    "segments",      "arc_geometry",
};
#define NATTRIBUTE ((int)(sizeof(kAttributes) / sizeof(kAttributes[0])))
#define FIRST_COEF_ATTRIBUTE 8
#define LAST_COEF_ATTRIBUTE 13  // E4; the keys after it are not stress-law coefficients
#define MAX_SEGMENTS 1024       // segments per muscle (config key `segments`)
// What could be built (musclefile.py refuses the same in a muscle file: PLAUSIBLE, BRAID_ANGLE_DEG,
// MIN_WALL_M, MAX_COEFFICIENT, MAX_DEADBAND_PA): outside these a config is a unit slip or a typo,
// and the muscle it describes runs to hundreds of metres or meganewtons without a word
#define MIN_SIZE_M 1e-4         // rest length and diameter: 0.1 mm ..
#define MAX_SIZE_M 10.0         // .. 10 m
#define MAX_VOLUME_M3 1.0       // bladder rubber volume
#define MIN_BRAID_DEG 2.0       // braid angle at rest, from the circumference
#define MAX_BRAID_DEG 88.0
#define MIN_WALL_M 1e-5         // bladder wall at rest
#define MAX_COEFFICIENT 1e12    // |stress-law coefficient|: stiffer than diamond
#define MAX_DEADBAND_PA 1.0e6   // the largest pressure the package drives a muscle with
// muscle.MIN_DEADBAND_PA, ZERO_DEADBAND_PA: a dead band of 1 .. 100 Pa is a kPa value written as Pa
// (no pressure sensor tells it from none); below 1 Pa it is 0 for every purpose (a fit's zero)
#define MIN_DEADBAND_PA 100.0
#define ZERO_DEADBAND_PA 1.0
#define MAX_PRESSURE_LAG_S 60.0  // muscle.MAX_PRESSURE_LAG_S: a filter's dynprm[0], seconds
#define EXPONENT_E4_MAX 10.0     // stress.EXPONENT_E4_MAX: the exponent law's stiffening exponent
#define MIN_E1_PA 1e4           // bladder modulus (stress.E1_PLAUSIBLE_PA): soft silicone ..
#define MAX_E1_PA 5e7           // .. stiff rubber
#define MAX_LOCK_STIFFNESS 1e9  // N/m, as a muscle file's lock_stiffness_N_per_m

// ----------------------------------------------------- scalar helpers (shared with efam_effects.h)

// pow through a volatile pointer: the compiler must not turn pow(x, 2.0) into x*x, which can
// differ from libm's pow in the last bit, and Python's float ** 2 calls libm's pow.
static double libm_pow(double x, double y) {
  double (*volatile fn)(double, double) = pow;
  return fn(x, y);
}

static double max0(double x) { return x > 0.0 ? x : 0.0; }  // np.maximum(x, 0.0) for finite x

static double clip(double x, double lo, double hi) {  // np.clip: minimum(maximum(x, lo), hi)
  double y = x > lo ? x : lo;
  return y < hi ? y : hi;
}

static double sign(double x) { return (x > 0.0) - (x < 0.0); }

static double signed_power(double e, double p) { return sign(e) * pow(fabs(e), p); }

// stress.StressLaw.__call__: (E1 + E2 P) eps + the law's non-linear term.
static double law_stress(Law law, const double* c, double arccot_scale, double e, double P) {
  double linear = (c[0] + c[1] * P) * e;
  switch (law) {
    case LAW_POLYNOMIAL:
      return linear + (c[2] * (e * e) + c[3] * pow(e, 3.0));
    case LAW_EXP_DECAY:
      return linear + c[2] * (1.0 - exp(-c[3] * e));
    case LAW_EXPONENT:
      return linear + c[0] * (signed_power(e, c[2]) + signed_power(e, c[3]));
    case LAW_SIGMOID:
      return linear + c[2] * tanh(c[3] * e);
    case LAW_ARCCOT:
      return linear + arccot_scale * atan(c[3] * e);
    default:
      return linear;
  }
}

// Eq. 11: t_B = R_o - sqrt(R_o^2 - V_B / (pi L)).
static double wall(double volume, double L, double r_out) {
  double inner_sq = max0(r_out * r_out - volume / (M_PI * L));
  return r_out - sqrt(inner_sq);
}

// The control as given (clamped), `delayed` through the actuator's ctrl delay when it has one.
static double control_pressure(const mjModel* m, const mjData* d, int i, int delayed) {
  int u = m->actuator_ctrladr[i];
  double ctrl = d->ctrl[u];
  if (delayed && m->actuator_delay[i] > 0 && m->actuator_historyadr[i] >= 0) {
    double interpolated;
    const mjtNum* read = mj_readCtrl(m, d, i, d->time, &interpolated, m->actuator_history[2 * i + 1]);
    ctrl = read ? *read : interpolated;
  }
  if (m->actuator_ctrllimited[u] && !mjDISABLED(mjDSBL_CLAMPCTRL)) {
    ctrl = clip(ctrl, m->actuator_ctrlrange[2 * u], m->actuator_ctrlrange[2 * u + 1]);
  }
  return ctrl;
}

// The measured pressure: the clamped (and delayed) control, as MuJoCo feeds its filter.
static double measured_pressure(const mjModel* m, const mjData* d, int i) {
  return control_pressure(m, d, i, 1);
}

// The transducer's pressure under the effect pressure_lag: the clamped control before the line's
// transport delay (pressure_lag.delay_s rides on the actuator's ctrl delay, which is the line's,
// downstream of the transducer the recording read).
static double transducer_pressure(const mjModel* m, const mjData* d, int i) {
  return control_pressure(m, d, i, 0);
}

// effect terms (config key `effects`): their own file; hooks below are marked efam_effects.h
#include "efam_effects.h"

// ------------------------------------------------------------------------------ the muscle

typedef struct {
  // config
  double rest_length, rest_diameter, theta_rest_deg, bladder_volume, deadband, lock_stiffness;
  Law law;
  double coef[4];  // E1..E4, unused ones zero (stress._pad)
  int tension_only;

  // derived exactly as Muscle.__post_init__
  double turns, thread, min_length, max_length, rest_outer_radius, rest_wall;

  // constants of the force expression, precomputed in the order Python evaluates them
  double thread_sq_pow;   // thread**2 (libm pow, as Python)
  double thread_sq_mul;   // B * B
  double two_pi_turns;    // 2 * pi * N
  double pressure_denom;  // 4 * pi * N * N
  double rest_mid_radius; // rest_outer_radius - rest_wall / 2
  double arccot_scale;    // E3 * (2 / pi)

  EffectsConfig effects;  // efam_effects.h: the effect terms switched on (count 0: none)

  // segmented muscles (config key `segments` = N > 1): each actuator drives the tendon of the
  // whole muscle, and the N tendons that follow it (in tendon order) are its segments between
  // consecutive spacer disks, all of equal resting length. Segment k pushes like the whole
  // muscle at N times its length (uniform deformation), at the muscle's one pressure state.
  int segments;

  // arc geometry (config key `arc_geometry` = 1, segmented arms): each segment's length is the
  // length of the muscle's arc in its half-link, computed from the link's joints (see
  // "arc geometry" below), not the fixed tendon's linear approximation. Model constants.
  int arc_geometry;
  struct ArcGeometry* arc;

  // the actuators this instance drives
  // pressure sensors (<sensor><plugin instance=.../>): where each writes its nactuator values
  int nsensor;
  int sensor_adr[MAX_PRESSURE_SENSORS];

  int nactuator;
  int actuator[];
} Muscle;

static double stress(const Muscle* mu, double e, double P) {
  return law_stress(mu->law, mu->coef, mu->arccot_scale, e, P);
}

// Eq. 10: R_o(L) = sqrt(B^2 - L^2) / (2 pi N).
static double outer_radius(const Muscle* mu, double L) {
  return sqrt(max0(mu->thread_sq_pow - L * L)) / mu->two_pi_turns;
}

// Muscle.tension for one (pressure, length): Eq. 2 with the documented out-of-range behaviour
// (paper sign: pull > 0). Used for instances that drive few actuators, where a batch does not pay.
static double muscle_tension(const Muscle* mu, double pressure, double length) {
  if (!isfinite(pressure) || !isfinite(length)) {
    return 0.0;
  }
  double P = max0(pressure);
  double L = clip(length, mu->min_length, mu->max_length);
  double N = mu->turns, V = mu->bladder_volume;

  double r_out = outer_radius(mu, L);
  double t = wall(V, L, r_out);
  double eps_z = L / mu->rest_length - 1.0;
  double eps_c = (r_out - t / 2) / mu->rest_mid_radius - 1.0;
  double sigma_z = stress(mu, eps_z, P);
  double sigma_c = stress(mu, eps_c, P);
  double gauge = max0(P - mu->deadband);
  double force = gauge / mu->pressure_denom * (3 * L * L - mu->thread_sq_mul) + sigma_z * V / L -
                 sigma_c * t * L * L / (2 * M_PI * r_out * N * N);
  force = force + mu->lock_stiffness * (length - L);
  if (mu->tension_only) {
    force = max0(force);
  }
  // an overflowing law (e.g. exp of a huge argument) must not hand MuJoCo inf or NaN
  return isfinite(force) ? force : 0.0;
}

// ----------------------------------------------------------------- the force, in batches
//
// An instance may drive many actuators (the arm and rig builders give all muscles with the same
// constants one instance). Their forces are computed as a batch, one stage per loop over plain
// arrays, with no branches inside the loops, so that the compiler turns them into vector
// instructions: the divisions, square roots and exponentials of Eq. 2 are what the plugin costs,
// and vectors of 4 or 8 doubles cut that cost several times. Each stage evaluates the same
// expressions in the same order as muscle.py (only e^3 is e*e*e here and pow in numpy, and
// exp is exp_batch below, not libm: both within two roundings).

#define BATCH 64     // actuators per pass (stack arrays)
#define MIN_BATCH 4  // fewer actuators in an instance: the scalar muscle_tension is cheaper

static double pick(int condition, double yes, double no) { return condition ? yes : no; }
static int finite_number(double x) { return x - x == 0.0; }  // false for inf and NaN

// max(x, 0) without a branch, exactly for finite x: x + |x| is 2x or 0, halving is exact. Loops
// of arithmetic vectorise on every x86-64 clone, loops of selects (x > 0 ? x : 0) only on some.
static double ramp(double x) { return 0.5 * (x + fabs(x)); }

// out[i] = exp(x[i]) for i < n <= 2 BATCH, to about one rounding, in vectorising passes:
// x = n ln2 + r (Cody-Waite split of ln2), exp(r) by its Taylor series to degree 13 (|r| <=
// ln2/2: truncation below 1e-17); then 2^n by writing n + 1023 into the exponent bits (an
// integer pass); then the product. Below -708 it returns 0 and above 709 inf (where libm gives
// a subnormal or a finite 1e308: the force is not finite then, and the plugin writes 0).
#if defined(__GNUC__)
__attribute__((always_inline))  // inlined into each vector clone of tension_batch
#endif
static inline void exp_batch(int n, const double* restrict x, double* restrict out) {
  const double shifter = 0x1.8p52, log2e = 1.4426950408889634;
  const double ln2_hi = 6.93147180369123816490e-01, ln2_lo = 1.90821492927058770002e-10;
  double k[2 * BATCH];
  const union { double d; uint64_t u; } shift = {shifter};
  for (int i = 0; i < n; i++) {
    double xc = x[i] - ramp(x[i] - 709.0);  // exact inside [-708, 709]; outside replaced below
    xc = xc + ramp(-708.0 - xc);
    k[i] = xc * log2e + shifter;  // n in the low bits of k: rounded to nearest
    double whole = k[i] - shifter;
    double r = (xc - whole * ln2_hi) - whole * ln2_lo;
    double p = 1.0 / 6227020800.0;
    p = p * r + 1.0 / 479001600.0;
    p = p * r + 1.0 / 39916800.0;
    p = p * r + 1.0 / 3628800.0;
    p = p * r + 1.0 / 362880.0;
    p = p * r + 1.0 / 40320.0;
    p = p * r + 1.0 / 5040.0;
    p = p * r + 1.0 / 720.0;
    p = p * r + 1.0 / 120.0;
    p = p * r + 1.0 / 24.0;
    p = p * r + 1.0 / 6.0;
    p = p * r + 0.5;
    p = p * r + 1.0;
    out[i] = p * r + 1.0;
  }
  for (int i = 0; i < n; i++) {
    union { double d; uint64_t u; } scale = {k[i]};
    scale.u = (scale.u - shift.u + 1023u) << 52;  // 2^n, n in [-1022, 1023]
    out[i] = out[i] * scale.d;
  }
  for (int i = 0; i < n; i++) {  // (selects in passes of their own: see ramp)
    out[i] = pick(x[i] < -708.0, 0.0, out[i]);
  }
  for (int i = 0; i < n; i++) {
    out[i] = pick(x[i] > 709.0, INFINITY, out[i]);
  }
}

#if defined(__GNUC__) && defined(__x86_64__) && !defined(_WIN32)
// one build for every x86-64; the loader picks the widest vectors the CPU has
#define EFAM_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define EFAM_VECTOR_CLONES
#endif

// Muscle.tension for n <= BATCH (pressure, length) pairs: Eq. 2 with the documented
// out-of-range behaviour (paper sign: pull > 0).
EFAM_VECTOR_CLONES
static void tension_batch(const Muscle* mu, int n, const double* restrict pressure,
                          const double* restrict length, double* restrict tension) {
  double ok[BATCH], P[BATCH], L[BATCH], L_unclamped[BATCH], r_out[BATCH], t[BATCH];
  double eps[2 * BATCH], sigma[2 * BATCH];  // z strains in [0, n), c strains in [n, 2n)
  const double lo = mu->min_length, hi = mu->max_length, V = mu->bladder_volume, N = mu->turns;
  const double* c = mu->coef;

  // inputs MuJoCo may hand over: non-finite (force 0), negative pressure, lengths out of range
  for (int i = 0; i < n; i++) {
    int finite = finite_number(pressure[i]) & finite_number(length[i]);
    ok[i] = finite;
    double p = pick(finite, pressure[i], 0.0);
    P[i] = pick(p > 0.0, p, 0.0);
    double l = pick(finite, length[i], mu->rest_length);
    L_unclamped[i] = l;
    l = pick(l > lo, l, lo);
    L[i] = pick(l < hi, l, hi);
  }
  // geometry, Eqs. 10-13, and the law's linear part (E1 + E2 P) eps
  for (int i = 0; i < n; i++) {
    r_out[i] = sqrt(ramp(mu->thread_sq_pow - L[i] * L[i])) / mu->two_pi_turns;
    t[i] = r_out[i] - sqrt(ramp(r_out[i] * r_out[i] - V / (M_PI * L[i])));
    eps[i] = L[i] / mu->rest_length - 1.0;
    eps[n + i] = (r_out[i] - t[i] / 2) / mu->rest_mid_radius - 1.0;
    double stiffness = c[0] + c[1] * P[i];
    sigma[i] = stiffness * eps[i];
    sigma[n + i] = stiffness * eps[n + i];
  }
  // the law's non-linear term at both strains
  int m = 2 * n;
  switch (mu->law) {
    case LAW_POLYNOMIAL:
      for (int i = 0; i < m; i++) {
        sigma[i] += c[2] * (eps[i] * eps[i]) + c[3] * (eps[i] * eps[i] * eps[i]);
      }
      break;
    case LAW_EXP_DECAY: {
      double arg[2 * BATCH], e[2 * BATCH];
      for (int i = 0; i < m; i++) {
        arg[i] = -c[3] * eps[i];
      }
      exp_batch(m, arg, e);
      for (int i = 0; i < m; i++) {
        sigma[i] += c[2] * (1.0 - e[i]);
      }
      break;
    }
    case LAW_EXPONENT:  // libm pow: not vectorised
      for (int i = 0; i < m; i++) {
        sigma[i] += c[0] * (signed_power(eps[i], c[2]) + signed_power(eps[i], c[3]));
      }
      break;
    case LAW_SIGMOID:
      for (int i = 0; i < m; i++) {
        sigma[i] += c[2] * tanh(c[3] * eps[i]);
      }
      break;
    case LAW_ARCCOT:
      for (int i = 0; i < m; i++) {
        sigma[i] += mu->arccot_scale * atan(c[3] * eps[i]);
      }
      break;
    default:
      break;
  }
  // Eq. 2 and the lock-out spring beyond the admissible range
  for (int i = 0; i < n; i++) {
    double Li = L[i];
    double force = ramp(P[i] - mu->deadband) / mu->pressure_denom * (3 * Li * Li - mu->thread_sq_mul) +
                   sigma[i] * V / Li - sigma[n + i] * t[i] * Li * Li / (2 * M_PI * r_out[i] * N * N);
    tension[i] = force + mu->lock_stiffness * (L_unclamped[i] - Li);
  }
  if (mu->tension_only) {
    for (int i = 0; i < n; i++) {
      tension[i] = pick(tension[i] < 0.0, 0.0, tension[i]);
    }
  }
  // a non-finite input, or an overflowing law (e.g. exp of a huge argument), gives 0: MuJoCo
  // must never see inf or NaN
  for (int i = 0; i < n; i++) {
    tension[i] = pick((ok[i] != 0.0) & finite_number(tension[i]), tension[i], 0.0);
  }
}

// ------------------------------------------------------------------- admissible lengths

typedef struct {
  double thread_sq, c;
} FillCubic;

// L (B^2 - L^2) - 4 pi N^2 V: positive where the bladder fits inside the sleeve.
static double fill_margin(const FillCubic* g, double L) { return L * (g->thread_sq - L * L) - g->c; }

// Brent's root bracketing method (Brent 1973, ch. 4) in the variant scipy.optimize.brentq
// implements, step for step, so that the root lands on the same double as in the Python model.
static double brent_root(const FillCubic* g, double a, double b, double xtol, double rtol) {
  double x_prev = a, f_prev = fill_margin(g, a);
  double x_cur = b, f_cur = fill_margin(g, b);
  double x_blk = 0.0, f_blk = 0.0, step_prev = 0.0, step_cur = 0.0;
  if (f_prev == 0.0) {
    return x_prev;
  }
  if (f_cur == 0.0) {
    return x_cur;
  }
  for (int iter = 0; iter < BRENT_MAXITER; iter++) {
    if (f_prev * f_cur < 0) {  // keep the bracket: x_blk is on the other side of the root
      x_blk = x_prev;
      f_blk = f_prev;
      step_prev = step_cur = x_cur - x_prev;
    }
    if (fabs(f_blk) < fabs(f_cur)) {  // make x_cur the best estimate
      x_prev = x_cur, x_cur = x_blk, x_blk = x_prev;
      f_prev = f_cur, f_cur = f_blk, f_blk = f_prev;
    }
    double tol = (xtol + rtol * fabs(x_cur)) / 2;
    double half = (x_blk - x_cur) / 2;
    if (f_cur == 0 || fabs(half) < tol) {
      return x_cur;
    }
    int bisect = 1;
    if (fabs(step_prev) > tol && fabs(f_cur) < fabs(f_prev)) {
      double trial;
      if (x_prev == x_blk) {  // secant
        trial = -f_cur * (x_cur - x_prev) / (f_cur - f_prev);
      } else {  // inverse quadratic
        double slope_prev = (f_prev - f_cur) / (x_prev - x_cur);
        double slope_blk = (f_blk - f_cur) / (x_blk - x_cur);
        trial = -f_cur * (f_blk * slope_blk - f_prev * slope_prev) / (slope_blk * slope_prev * (f_blk - f_prev));
      }
      double limit = fabs(step_prev) < 3 * fabs(half) - tol ? fabs(step_prev) : 3 * fabs(half) - tol;
      if (2 * fabs(trial) < limit) {
        step_prev = step_cur;
        step_cur = trial;
        bisect = 0;
      }
    }
    if (bisect) {
      step_prev = step_cur = half;
    }
    x_prev = x_cur;
    f_prev = f_cur;
    x_cur += fabs(step_cur) > tol ? step_cur : (half > 0 ? tol : -tol);
    f_cur = fill_margin(g, x_cur);
  }
  return x_cur;
}

// ---------------------------------------------------------------------------- config errors

// Who the message is about: the first actuator the instance drives, else the instance itself.
static const char* instance_label(const mjModel* m, int instance, char* buf, size_t size) {
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] == instance) {
      const char* name = m->names + m->name_actuatoradr[i];
      if (name[0]) {
        snprintf(buf, size, "actuator '%s'", name);
      } else {
        snprintf(buf, size, "actuator %d", i);
      }
      return buf;
    }
  }
  const char* name = m->names + m->name_pluginadr[instance];
  if (name[0]) {
    snprintf(buf, size, "instance '%s'", name);
  } else {
    snprintf(buf, size, "plugin instance %d", instance);
  }
  return buf;
}

#define CONFIG_ERROR(m, instance, fmt, ...)                                                    \
  do {                                                                                         \
    char label_[160];                                                                          \
    mju_error(PLUGIN_NAME " (%s): " fmt, instance_label(m, instance, label_, sizeof(label_)), \
              __VA_ARGS__);                                                                    \
  } while (0)

static const char* config_value(const mjModel* m, int instance, const char* key) {
  const char* value = mj_getPluginConfig(m, instance, key);
  return value && value[0] ? value : NULL;
}

// A finite number, or an error naming the key. Missing optional keys give the default.
static double read_number(const mjModel* m, int instance, const char* key, int required, double fallback) {
  const char* text = config_value(m, instance, key);
  if (!text) {
    if (required) {
      CONFIG_ERROR(m, instance, "missing config key '%s'", key);
    }
    return fallback;
  }
  // plain decimal only: strtod also reads hexadecimal ("0x1p-3" = 0.125), which no one means here
  for (const char* c = text; *c; c++) {
    if (*c == 'x' || *c == 'X' || *c == 'p' || *c == 'P') {
      CONFIG_ERROR(m, instance, "config key '%s' must be a decimal number, got '%s'", key, text);
    }
  }
  char* end = NULL;
  errno = 0;
  double value = strtod(text, &end);
  while (end && (*end == ' ' || *end == '\t' || *end == '\n')) {
    end++;
  }
  if (end == text || (end && *end) || !isfinite(value)) {
    CONFIG_ERROR(m, instance, "config key '%s' must be a finite number, got '%s'", key, text);
  }
  return value;
}

static void require(const mjModel* m, int instance, int ok, const char* key, double value, const char* rule) {
  if (!ok) {
    CONFIG_ERROR(m, instance, "config key '%s' = %.10g is invalid: %s", key, value, rule);
  }
}

static Law read_law(const mjModel* m, int instance) {
  const char* text = config_value(m, instance, "law");
  if (!text) {
    CONFIG_ERROR(m, instance, "missing config key '%s' (one of: %s)", "law",
                 "linear, polynomial, exponential_decay, exponent, sigmoid, arccot");
  }
  for (int k = 0; k < NLAW; k++) {
    if (strcmp(text, kLaws[k].name) == 0) {
      return (Law)k;
    }
  }
  CONFIG_ERROR(m, instance, "config key 'law' = '%s' is not a known stress law (known: %s)", text,
               "linear, polynomial, exponential_decay, exponent, sigmoid, arccot");
  return LAW_LINEAR;
}

static int read_flag(const mjModel* m, int instance, const char* key) {
  const char* text = config_value(m, instance, key);
  if (!text || strcmp(text, "0") == 0 || strcmp(text, "false") == 0) {
    return 0;
  }
  if (strcmp(text, "1") == 0 || strcmp(text, "true") == 0) {
    return 1;
  }
  CONFIG_ERROR(m, instance, "config key '%s' must be \"0\" or \"1\" (or \"false\" or \"true\"), got '%s'", key, text);
  return 0;
}

static int law_has_key(const LawSpec* law, const char* key) {
  for (int k = 0; k < law->ncoef; k++) {
    if (strcmp(law->keys[k], key) == 0) {
      return 1;
    }
  }
  return 0;
}

static void read_coefficients(const mjModel* m, int instance, Muscle* mu) {
  const LawSpec* law = &kLaws[mu->law];
  char expected[64] = "";
  for (int k = 0; k < law->ncoef; k++) {
    strcat(expected, k ? ", " : "");
    strcat(expected, law->keys[k]);
  }
  // a coefficient of another law is a mistake (E3 given where E3_Pa is meant, say)
  for (int a = FIRST_COEF_ATTRIBUTE; a <= LAST_COEF_ATTRIBUTE; a++) {
    if (config_value(m, instance, kAttributes[a]) && !law_has_key(law, kAttributes[a])) {
      CONFIG_ERROR(m, instance, "config key '%s' is not a coefficient of stress law '%s' (expected %s)",
                   kAttributes[a], law->name, expected);
    }
  }
  for (int k = 0; k < 4; k++) {
    mu->coef[k] = 0.0;
  }
  for (int k = 0; k < law->ncoef; k++) {
    const char* key = law->keys[k];
    if (!config_value(m, instance, key)) {
      CONFIG_ERROR(m, instance, "missing config key '%s' for stress law '%s' (expected %s)", key, law->name,
                   expected);
    }
    double value = read_number(m, instance, key, 1, 0.0);
    if (fabs(value) > MAX_COEFFICIENT) {
      CONFIG_ERROR(m, instance, "config key '%s' = %.10g is beyond 1e12 in magnitude: no rubber's stress law "
                   "comes near it (a unit slip?)", key, value);
    }
    Bound b = law->bounds[k];
    int too_low = b.lo_open ? value <= b.lo : value < b.lo;
    int too_high = b.hi_open ? value >= b.hi : value > b.hi;
    if (too_low || too_high) {
      CONFIG_ERROR(m, instance, "config key '%s' = %.10g is outside %s%g, %g%s for stress law '%s'", key, value,
                   b.lo_open ? "(" : "[", b.lo, b.hi, b.hi_open ? ")" : "]", law->name);
    }
    mu->coef[k] = value;
  }
}

// Muscle.strains at one length: the longitudinal and circumferential strains.
static void strains(const Muscle* mu, double L, double* eps_z, double* eps_c) {
  double r_out = outer_radius(mu, L);
  double t = wall(mu->bladder_volume, L, r_out);
  *eps_z = L / mu->rest_length - 1.0;
  *eps_c = (r_out - t / 2) / mu->rest_mid_radius - 1.0;
}

// Drucker stability over the muscle's strain range (StressLaw.check_stable with
// Muscle.strain_range): d sigma / d eps > 0 at zero pressure.
static void check_stable(const mjModel* m, int instance, const Muscle* mu) {
  double lo = INFINITY, hi = -INFINITY;
  double step = (mu->max_length - mu->min_length) / (STRAIN_SAMPLES - 1);
  for (int i = 0; i < STRAIN_SAMPLES; i++) {
    double L = i == STRAIN_SAMPLES - 1 ? mu->max_length : i * step + mu->min_length;
    double ez, ec;
    strains(mu, L, &ez, &ec);
    lo = fmin(lo, fmin(ez, ec));
    hi = fmax(hi, fmax(ez, ec));
  }
  const double* c = mu->coef;
  double worst = c[0];
  if (mu->law == LAW_POLYNOMIAL) {
    double candidates[3] = {lo, hi, lo};
    int n = 2;
    if (c[3] != 0.0) {
      double vertex = -c[2] / (3.0 * c[3]);
      if (lo < vertex && vertex < hi) {
        candidates[n++] = vertex;
      }
    }
    worst = INFINITY;
    for (int k = 0; k < n; k++) {
      double e = candidates[k];
      worst = fmin(worst, c[0] + 2.0 * c[2] * e + 3.0 * c[3] * e * e);
    }
  }
  if (!(worst > 0.0)) {
    CONFIG_ERROR(m, instance,
                 "stress law '%s' is not Drucker-stable: d sigma/d eps = %.4g Pa <= 0 for strains in "
                 "[%.3g, %.3g]; check config keys E1_Pa, E3_Pa, E4_Pa",
                 kLaws[mu->law].name, worst, lo, hi);
  }
}

// Muscle.__post_init__ and _admissible_lengths: the derived constants.
static void derive(const mjModel* m, int instance, Muscle* mu) {
  double theta = mu->theta_rest_deg * (M_PI / 180.0);  // math.radians
  mu->turns = mu->rest_length / (M_PI * mu->rest_diameter * tan(theta));  // Eq. 4
  mu->thread = mu->rest_length / sin(theta);                              // Eq. 3
  mu->rest_outer_radius = mu->rest_diameter / 2;

  FillCubic g = {libm_pow(mu->thread, 2), 4 * M_PI * libm_pow(mu->turns, 2) * mu->bladder_volume};
  double peak = mu->thread / sqrt(3.0);
  if (peak * (libm_pow(mu->thread, 2) - libm_pow(peak, 2)) <= g.c) {
    CONFIG_ERROR(m, instance,
                 "config key 'bladder_volume_m3' = %.6g: the bladder does not fit inside the sleeve at any "
                 "length (check rest_length_m, rest_diameter_m, theta_rest_deg)",
                 mu->bladder_volume);
  }
  mu->min_length = brent_root(&g, 0.0, peak, BRENT_XTOL, BRENT_RTOL);
  mu->max_length = brent_root(&g, peak, mu->thread, BRENT_XTOL, BRENT_RTOL);
  if (!(mu->min_length < mu->rest_length && mu->rest_length < mu->max_length)) {
    CONFIG_ERROR(m, instance,
                 "config key 'bladder_volume_m3' = %.6g: the bladder does not fit inside the sleeve at the "
                 "resting length rest_length_m = %.6g",
                 mu->bladder_volume, mu->rest_length);
  }
  mu->rest_wall = wall(mu->bladder_volume, mu->rest_length, mu->rest_outer_radius);
  if (!(mu->rest_wall >= MIN_WALL_M)) {
    CONFIG_ERROR(m, instance,
                 "config key 'bladder_volume_m3' = %.6g gives a bladder wall %.3g mm thick at rest, thinner than any "
                 "bladder (0.01 mm): it is the volume of the bladder's rubber, not of the air inside",
                 mu->bladder_volume, mu->rest_wall * 1e3);
  }

  mu->thread_sq_pow = libm_pow(mu->thread, 2);
  mu->thread_sq_mul = mu->thread * mu->thread;
  mu->two_pi_turns = 2 * M_PI * mu->turns;
  mu->pressure_denom = 4 * M_PI * mu->turns * mu->turns;
  mu->rest_mid_radius = mu->rest_outer_radius - mu->rest_wall / 2;
  mu->arccot_scale = mu->coef[2] * (2.0 / M_PI);
}

static int actuator_count(const mjModel* m, int instance) {
  int n = 0;
  for (int i = 0; i < m->nactuator; i++) {
    n += m->actuator_plugin[i] == instance;
  }
  return n;
}

// One pressure per actuator: a scalar control, and at most the one activation state MuJoCo's
// own first-order dynamics keeps.
static void check_actuators(const mjModel* m, int instance) {
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] != instance) {
      continue;
    }
    int dyntype = m->actuator_dyntype[i];
    if (dyntype != mjDYN_NONE && dyntype != mjDYN_INTEGRATOR && dyntype != mjDYN_FILTER &&
        dyntype != mjDYN_FILTEREXACT) {
      CONFIG_ERROR(m, instance, "dyntype %d is not supported (use none, filter, filterexact or integrator)%s",
                   dyntype, "");
    }
    int expected = dyntype == mjDYN_NONE ? 0 : 1;
    if (m->actuator_actnum[i] != expected) {
      CONFIG_ERROR(m, instance, "actdim is %d, expected %d for this dyntype: set actdim=\"%d\" on the plugin actuator",
                   m->actuator_actnum[i], expected, expected);
    }
    if (m->actuator_ctrlnum[i] != 1 || m->actuator_outnum[i] != 1) {
      CONFIG_ERROR(m, instance, "needs a scalar transmission (one control, one force output)%s", "");
    }
    // the pressure lag's time constant (rig.actuator_xml writes it; 0 is no lag, as MuJoCo reads it)
    double tau = m->actuator_dynprm[i * mjNDYN];
    if ((dyntype == mjDYN_FILTER || dyntype == mjDYN_FILTEREXACT) && !(tau >= 0 && tau <= MAX_PRESSURE_LAG_S)) {
      CONFIG_ERROR(m, instance,
                   "actuator %d: dynprm[0] = %.10g s, the pressure lag's time constant, must be in 0 .. %g s: a "
                   "valve and a tube fill a bladder in milliseconds to seconds (was it in ms?)",
                   i, tau, MAX_PRESSURE_LAG_S);
    }
  }
}

// segmented muscles and their arc geometry (below the callbacks)
static void check_segments(const mjModel* m, int instance, const Muscle* mu);
static void add_segment_forces(const mjModel* m, mjData* d, const Muscle* mu);
static void check_arc_geometry(const mjModel* m, int instance, const Muscle* mu);
static struct ArcGeometry* arc_build(const mjModel* m, const Muscle* mu);
static struct ArcGeometry* arc_clone(const struct ArcGeometry* from);

// Read, validate and derive everything before allocating, so that an error (which does not
// return) leaks nothing.
static Muscle* muscle_create(const mjModel* m, int instance) {
  int nact = actuator_count(m, instance);  // may be 0: a declared muscle no actuator uses yet
  check_actuators(m, instance);

  Muscle mu;
  memset(&mu, 0, sizeof(mu));
  mu.rest_length = read_number(m, instance, "rest_length_m", 1, 0.0);
  mu.rest_diameter = read_number(m, instance, "rest_diameter_m", 1, 0.0);
  mu.theta_rest_deg = read_number(m, instance, "theta_rest_deg", 1, 0.0);
  mu.bladder_volume = read_number(m, instance, "bladder_volume_m3", 1, 0.0);
  mu.deadband = read_number(m, instance, "deadband_Pa", 1, 0.0);
  mu.lock_stiffness = read_number(m, instance, "lock_stiffness_N_per_m", 0, DEFAULT_LOCK_STIFFNESS);
  mu.tension_only = read_flag(m, instance, "tension_only");
  require(m, instance, mu.rest_length >= MIN_SIZE_M && mu.rest_length <= MAX_SIZE_M, "rest_length_m",
          mu.rest_length, "must be in 0.0001 .. 10 m (was it in mm?)");
  require(m, instance, mu.rest_diameter >= MIN_SIZE_M && mu.rest_diameter <= MAX_SIZE_M, "rest_diameter_m",
          mu.rest_diameter, "must be in 0.0001 .. 10 m (was it in mm?)");
  require(m, instance, mu.theta_rest_deg >= MIN_BRAID_DEG && mu.theta_rest_deg <= MAX_BRAID_DEG,
          "theta_rest_deg", mu.theta_rest_deg, "must be in 2 .. 88 deg: no braided sleeve is wound outside it");
  require(m, instance, mu.bladder_volume > 0 && mu.bladder_volume <= MAX_VOLUME_M3, "bladder_volume_m3",
          mu.bladder_volume, "must be in (0, 1] m^3");
  require(m, instance, mu.deadband >= 0 && mu.deadband < MAX_DEADBAND_PA, "deadband_Pa", mu.deadband,
          "must be in 0 .. 1e6 Pa: at 1000 kPa or more the muscle never inflates (was it in kPa?)");
  require(m, instance, !(mu.deadband >= ZERO_DEADBAND_PA && mu.deadband < MIN_DEADBAND_PA), "deadband_Pa",
          mu.deadband,
          "a dead band below 100 Pa is under what a pressure sensor tells from none (the paper's are 34 kPa): "
          "was it in kPa? Write 0 for no dead band");
  require(m, instance, mu.lock_stiffness >= 0 && mu.lock_stiffness <= MAX_LOCK_STIFFNESS, "lock_stiffness_N_per_m",
          mu.lock_stiffness, "must be in 0 .. 1e9 N/m");
  mu.law = read_law(m, instance);
  read_coefficients(m, instance, &mu);
  require(m, instance, mu.coef[0] >= MIN_E1_PA && mu.coef[0] <= MAX_E1_PA, "E1_Pa", mu.coef[0],
          "cannot be physical for a bladder: its modulus lies in 1e4 .. 5e7 Pa (was it in MPa?)");
  require(m, instance, mu.law != LAW_EXPONENT || mu.coef[3] <= EXPONENT_E4_MAX, "E4", mu.coef[3],
          "cannot be physical: the exponent law's strain-stiffening exponent of a rubber bladder lies in 1 .. 10 "
          "(the paper's are 1.35 and 1.52)");
  derive(m, instance, &mu);
  check_stable(m, instance, &mu);
  effects_configure(m, instance, &mu.effects, EFFECTS_MUSCLE_OF(mu));  // efam_effects.h
  double segments = read_number(m, instance, "segments", 0, 1.0);
  require(m, instance, segments >= 1 && segments <= MAX_SEGMENTS && segments == floor(segments), "segments",
          segments, "must be a whole number from 1 to 1024");
  mu.segments = (int)segments;
  check_segments(m, instance, &mu);
  mu.arc_geometry = read_flag(m, instance, "arc_geometry");
  check_arc_geometry(m, instance, &mu);

  int nsensor = 0;
  for (int j = 0; j < m->nsensor; j++) {
    nsensor += m->sensor_type[j] == mjSENS_PLUGIN && m->sensor_plugin[j] == instance;
  }
  if (nsensor > MAX_PRESSURE_SENSORS) {
    CONFIG_ERROR(m, instance, "%d pressure sensors read this instance; at most %d may", nsensor,
                 MAX_PRESSURE_SENSORS);
  }
  Muscle* out = (Muscle*)malloc(sizeof(Muscle) + sizeof(int) * (size_t)nact);
  if (!out) {
    return NULL;
  }
  *out = mu;
  out->nactuator = 0;
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] == instance) {
      out->actuator[out->nactuator++] = i;
    }
  }
  out->arc = NULL;
  if (out->arc_geometry) {  // checked above: building it cannot fail but for memory
    out->arc = arc_build(m, out);
    if (!out->arc) {
      free(out);
      return NULL;
    }
  }
  out->nsensor = 0;
  for (int j = 0; j < m->nsensor; j++) {
    if (m->sensor_type[j] == mjSENS_PLUGIN && m->sensor_plugin[j] == instance) {
      out->sensor_adr[out->nsensor++] = m->sensor_adr[j];
    }
  }
  return out;
}

// ------------------------------------------------------------------------- plugin callbacks

// The pressure the muscle sees: the (clamped) control, or the filtered pressure held in the
// actuator's activation; with actearly, the activation at the end of this step (as pid.cc).
static double actuator_pressure(const mjModel* m, const mjData* d, int i) {
  if (m->actuator_dyntype[i] == mjDYN_NONE) {
    return measured_pressure(m, d, i);
  }
  int adr = m->actuator_actadr[i] + m->actuator_actnum[i] - 1;
  double act = d->act[adr];
  if (!m->actuator_actearly[i]) {
    return act;
  }
  double act_dot = d->act_dot[adr];
  if (m->actuator_dyntype[i] == mjDYN_FILTEREXACT) {
    double tau = fmax(mjMINVAL, m->actuator_dynprm[i * mjNDYN]);
    act = act + act_dot * tau * (1 - exp(-m->opt.timestep / tau));
  } else {
    act = act + act_dot * m->opt.timestep;
  }
  if (m->actuator_actlimited[i]) {
    act = clip(act, m->actuator_actrange[2 * i], m->actuator_actrange[2 * i + 1]);
  }
  return act;
}

// The pressure state of actuator i, what a pressure sensor reads: the activation (the lagged
// pressure) of an actuator with dynamics, else the clamped control. (With actearly the force
// uses the activation at the end of the step; the sensor reports the state.)
static double pressure_state(const mjModel* m, const mjData* d, int i) {
  if (m->actuator_dyntype[i] == mjDYN_NONE) {
    return measured_pressure(m, d, i);
  }
  return d->act[m->actuator_actadr[i] + m->actuator_actnum[i] - 1];
}

// Sensor stage (mjSTAGE_POS: ctrl and act are state, and nothing else has to be computed first):
// every pressure sensor of this instance gets one value per actuator, in actuator order.
static void write_pressure_sensors(const mjModel* m, mjData* d, const Muscle* mu) {
  for (int s = 0; s < mu->nsensor; s++) {
    mjtNum* out = d->sensordata + mu->sensor_adr[s];
    for (int k = 0; k < mu->nactuator; k++) {
      out[k] = pressure_state(m, d, mu->actuator[k]);
    }
  }
}

static int muscle_nsensordata(const mjModel* m, int instance, int sensor_id) {
  return actuator_count(m, instance);
}

static void muscle_compute(const mjModel* m, mjData* d, int instance, int capability_bit) {
  const Muscle* mu = (const Muscle*)d->plugin_data[instance];
  if (!mu) {
    return;
  }
  if (capability_bit == mjPLUGIN_SENSOR) {
    write_pressure_sensors(m, d, mu);
    return;
  }
  if (capability_bit == mjPLUGIN_PASSIVE) {
    if (mu->segments > 1) {
      add_segment_forces(m, d, mu);
    }
    return;
  }
  if (mu->nactuator < MIN_BATCH) {
    for (int k = 0; k < mu->nactuator; k++) {
      int i = mu->actuator[k];
      int out = m->actuator_outadr[i];
      d->actuator_force[out] = -muscle_tension(mu, actuator_pressure(m, d, i), d->actuator_length[out]);
    }
    if (mu->effects.count) {  // efam_effects.h: the effect terms (as after the batched path below)
      effects_add_forces(m, d, instance, &mu->effects, mu->actuator, mu->nactuator);
    }
    return;
  }
  double pressure[BATCH], length[BATCH], tension[BATCH];
  for (int first = 0; first < mu->nactuator; first += BATCH) {
    int n = mu->nactuator - first < BATCH ? mu->nactuator - first : BATCH;
    for (int k = 0; k < n; k++) {
      int i = mu->actuator[first + k];
      pressure[k] = actuator_pressure(m, d, i);
      length[k] = d->actuator_length[m->actuator_outadr[i]];
    }
    tension_batch(mu, n, pressure, length, tension);
    for (int k = 0; k < n; k++) {
      d->actuator_force[m->actuator_outadr[mu->actuator[first + k]]] = -tension[k];
    }
  }
  if (mu->effects.count) {  // efam_effects.h: the effect terms, on top of the forces just written
    effects_add_forces(m, d, instance, &mu->effects, mu->actuator, mu->nactuator);
  }
}


// ------------------------------------------------------------------- segmented muscles
//
// With `segments` = N > 1 the actuator applies push(P, L) on the whole muscle's tendon (length
// L = the sum of its segments), and the passive stage adds, for every segment k,
// (push(P, N l_k) - push(P, L)) J_k: in total every segment carries its own force
// push(P, N l_k) along its own Jacobian J_k. The pressure is the actuator's state (ctrl, or the
// activation of its filter), so one pressure lag serves all segments of a muscle.

static void add_arc_segment_forces(const mjModel* m, mjData* d, const Muscle* mu);

static void add_segment_forces(const mjModel* m, mjData* d, const Muscle* mu) {
  if (mu->arc) {
    add_arc_segment_forces(m, d, mu);
    return;
  }
  const int N = mu->segments;
  double pressure[BATCH], length[BATCH], tension[BATCH];
  int tendon[BATCH];
  double whole[BATCH];  // push(P, L) of the actuator each batch entry belongs to
  int n = 0;
  for (int k = 0; k < mu->nactuator; k++) {
    int i = mu->actuator[k];
    int first = m->actuator_trnid[2 * i] + 1;
    double P = actuator_pressure(m, d, i);
    double L = d->actuator_length[m->actuator_outadr[i]];
    double whole_push = -muscle_tension(mu, P, L);
    for (int s = 0; s < N; s++) {
      pressure[n] = P;
      length[n] = N * d->ten_length[first + s];
      tendon[n] = first + s;
      whole[n] = whole_push;
      n++;
      if (n == BATCH || (k == mu->nactuator - 1 && s == N - 1)) {
        tension_batch(mu, n, pressure, length, tension);
        for (int e = 0; e < n; e++) {
          double extra = -tension[e] - whole[e];
          int t = tendon[e], adr = m->ten_J_rowadr[t];
          for (int c = 0; c < m->ten_J_rownnz[t]; c++) {
            d->qfrc_passive[m->ten_J_colind[adr + c]] += extra * d->ten_J[adr + c];
          }
        }
        n = 0;
      }
    }
  }
}

// Segmented muscles: every actuator of the instance drives the tendon of a whole muscle, its N
// segments follow that tendon, one pressure state (no actearly: the passive stage runs before
// the activation derivative is known), no effect terms (they are defined on a whole muscle).
static void check_segments(const mjModel* m, int instance, const Muscle* mu) {
  if (mu->segments == 1) {
    return;
  }
  if (mu->effects.count) {
    CONFIG_ERROR(m, instance, "config key 'segments' = %d: effect terms are not supported on segmented muscles%s",
                 mu->segments, "");
  }
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] != instance) {
      continue;
    }
    if (m->actuator_trntype[i] != mjTRN_TENDON) {
      CONFIG_ERROR(m, instance, "config key 'segments' = %d needs a tendon transmission (the whole muscle)%s",
                   mu->segments, "");
    }
    int first = m->actuator_trnid[2 * i] + 1;
    if (first + mu->segments > m->ntendon) {
      CONFIG_ERROR(m, instance,
                   "config key 'segments' = %d: the %d tendons after the muscle's tendon (its segments) "
                   "do not exist (%d tendons in the model)",
                   mu->segments, mu->segments, (int)m->ntendon);
    }
    if (m->actuator_actearly[i]) {
      CONFIG_ERROR(m, instance, "config key 'segments' = %d: actearly is not supported on segmented muscles%s",
                   mu->segments, "");
    }
  }
}

// ------------------------------------------------------------------------- arc geometry
//
// Config key `arc_geometry` = 1 (segmented muscles of the arm builder's links). A link is a slide
// ext_a along the previous disk's axis z, a universal joint at its node (hinges a about x and b
// about y, in the body's joint order), and a slide ext_b along the node's new axis. Its segment
// tendons are fixed tendons e + (y a - x b) / 2 (e the half-link's slide, (x, y) the muscle's
// offset): linear in the joints, which is right to first order in the bend. Exactly:
//
// * the tangents of an arc of bend theta have length e = R tan(theta / 2), its half-arcs R theta / 2:
//   the muscle's half-arc at the axis is e phi(theta), phi(t) = (t / 2) / tan(t / 2);
// * a universal joint turns the disk by Q = Rx(a) Ry(b) (or Ry(b) Rx(a)): a swing, the shortest
//   rotation taking z to Q z, by the angle theta (cos theta = cos a cos b) about the axis along
//   sigma = theta u / |u|, u = (sin a cos b, sin b) (x first; (sin a, cos a sin b) y first),
//   followed by a twist about the new axis, tau = +-2 atan2(sin(a/2) sin(b/2), cos(a/2) cos(b/2)).
//   The bundle does not twist (its spacer disks and clamped muscles keep it from it; the
//   continuum reference has no twist either): its disks are the swing-transported frames, and
//   a MuJoCo disk is the bundle's disk turned by the twist T its links have accumulated since
//   the last body that is not a link (the arm's base); swings commute with twists about z, so T
//   is the sum of the links' tau, and a link's swing in the bundle's frame is its own sigma
//   turned by T.
//
// So a muscle at offset (x, y) in the bundle's disk, at (x', y') = Rz(-T) (x, y) in the MuJoCo
// frame of the link's proximal disk, has in each half-link the arc length
//
//     l = e phi(theta) + (y' sigma_x - x' sigma_y) / 2,
//
// exact for a link bent at constant curvature in any plane (the arc's length at the muscle's
// offset). l is a smooth function of the joints (e, a, b) of its link and of every proximal
// link's (a, b) through T; the segment's force push(P, N l) acts along its gradient, so the
// forces derive from the muscles' energy at the segment lengths (conservative). Unloaded, every
// segment's force balance is the continuum's, so the arm is the continuum's constant-curvature
// arc at its disks, for any number of disks. The fixed tendons stay as they are (the actuator's
// whole-muscle length and the segments' Jacobians that the passive stage subtracts).

typedef struct {
  int qpos_a, qpos_b, dof_a, dof_b;  // hinges about x (a) and y (b)
  int x_first;                       // Q = Rx(a) Ry(b) (1) or Ry(b) Rx(a) (0)
  int parent;                        // nearest proximal link (index), -1 at the root
} ArcLink;

typedef struct {
  int link, slide_qpos, slide_dof;
  double x, y;  // the muscle's offset in the bundle's disk (from the tendon's coefficients)
} ArcSegment;

typedef struct ArcGeometry {
  int nlink, nseg;  // segments in actuator order, N per actuator
  ArcLink* link;    // both arrays live in this allocation, right after the struct
  ArcSegment* seg;
} ArcGeometry;

static ArcGeometry* arc_alloc(int nlink, int nseg) {
  ArcGeometry* g = (ArcGeometry*)malloc(sizeof(ArcGeometry) + sizeof(ArcLink) * (size_t)nlink +
                                        sizeof(ArcSegment) * (size_t)nseg);
  if (g) {
    g->nlink = nlink;
    g->nseg = nseg;
    g->link = (ArcLink*)(g + 1);
    g->seg = (ArcSegment*)(g->link + nlink);
  }
  return g;
}

static ArcGeometry* arc_clone(const ArcGeometry* from) {
  ArcGeometry* g = arc_alloc(from->nlink, from->nseg);
  if (g) {
    memcpy(g->link, from->link, sizeof(ArcLink) * (size_t)from->nlink);
    memcpy(g->seg, from->seg, sizeof(ArcSegment) * (size_t)from->nseg);
  }
  return g;
}

static int axis_is(const mjModel* m, int joint, double x, double y, double z) {
  const mjtNum* a = m->jnt_axis + 3 * joint;
  return a[0] == x && a[1] == y && a[2] == z;
}

// What body b is to the arc geometry: 1 a link (exactly two hinges, about its x and y axes, and
// otherwise only slides; *hx, *hy their joint ids), 0 a body that does not turn (slides only, or
// no joints), -1 anything else (the world, a ball, free or other hinge joint: the root).
static int link_kind(const mjModel* m, int b, int* hx, int* hy) {
  if (b <= 0) {
    return -1;
  }
  int nx = 0, ny = 0, other = 0;
  for (int j = m->body_jntadr[b]; j < m->body_jntadr[b] + m->body_jntnum[b]; j++) {
    if (m->jnt_type[j] == mjJNT_SLIDE) {
      continue;
    }
    if (m->jnt_type[j] == mjJNT_HINGE && axis_is(m, j, 1, 0, 0)) {
      nx++;
      *hx = j;
    } else if (m->jnt_type[j] == mjJNT_HINGE && axis_is(m, j, 0, 1, 0)) {
      ny++;
      *hy = j;
    } else {
      other++;
    }
  }
  if (other || nx > 1 || ny > 1 || nx != ny) {
    return -1;
  }
  return nx == 1 ? 1 : 0;
}

// The link body of segment tendon t, its slide and its muscle offset; an error message (in
// `why`) when the tendon is not a half-link's segment. Returns the node body or -1.
static int arc_segment_of(const mjModel* m, int t, ArcSegment* out, char* why, size_t size) {
  int slide = -1, hx = -1, hy = -1;
  double cx = 0, cy = 0, cslide = 0;
  if (m->tendon_num[t] != 3) {
    snprintf(why, size, "has %d wraps, a half-link's segment has 3 (its slide and two hinges)", m->tendon_num[t]);
    return -1;
  }
  for (int w = m->tendon_adr[t]; w < m->tendon_adr[t] + m->tendon_num[t]; w++) {
    int j = m->wrap_objid[w];
    if (m->wrap_type[w] != mjWRAP_JOINT) {
      snprintf(why, size, "is not a fixed tendon");
      return -1;
    }
    if (m->jnt_type[j] == mjJNT_SLIDE && axis_is(m, j, 0, 0, 1) && slide < 0) {
      slide = j;
      cslide = m->wrap_prm[w];
    } else if (m->jnt_type[j] == mjJNT_HINGE && axis_is(m, j, 1, 0, 0) && hx < 0) {
      hx = j;
      cx = m->wrap_prm[w];
    } else if (m->jnt_type[j] == mjJNT_HINGE && axis_is(m, j, 0, 1, 0) && hy < 0) {
      hy = j;
      cy = m->wrap_prm[w];
    }
  }
  if (slide < 0 || hx < 0 || hy < 0 || cslide != 1.0) {
    snprintf(why, size, "is not a slide along z (coefficient 1) and hinges about x and y");
    return -1;
  }
  int node = m->jnt_bodyid[hx], lx = -1, ly = -1;
  if (m->jnt_bodyid[hy] != node || link_kind(m, node, &lx, &ly) != 1) {
    snprintf(why, size, "has hinges that are not one body's universal joint (two hinges, x and y)");
    return -1;
  }
  int sb = m->jnt_bodyid[slide];
  if (sb != node && m->body_parentid[sb] != node) {
    snprintf(why, size, "has a slide that is neither in its link's node nor in the node's child");
    return -1;
  }
  out->slide_qpos = m->jnt_qposadr[slide];
  out->slide_dof = m->jnt_dofadr[slide];
  out->x = -2.0 * cy;  // the coefficients are y / 2 (about x) and -x / 2 (about y)
  out->y = 2.0 * cx;
  return node;
}

static void check_arc_geometry(const mjModel* m, int instance, const Muscle* mu) {
  if (!mu->arc_geometry) {
    return;
  }
  if (mu->segments < 2) {
    CONFIG_ERROR(m, instance, "config key 'arc_geometry' = 1 needs segmented muscles ('segments' > 1)%s", "");
  }
  char why[200];
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] != instance) {
      continue;
    }
    int first = m->actuator_trnid[2 * i] + 1;
    for (int s = 0; s < mu->segments; s++) {
      ArcSegment seg;
      if (arc_segment_of(m, first + s, &seg, why, sizeof(why)) < 0) {
        const char* name = m->names + m->name_tendonadr[first + s];
        CONFIG_ERROR(m, instance, "config key 'arc_geometry' = 1: segment tendon '%s' (%d) %s", name, first + s,
                     why);
      }
    }
  }
}

// The links every segment of this instance depends on (its own and all proximal ones), in body
// order (a parent body comes before its children in MuJoCo), and the segments. Checked before.
static ArcGeometry* arc_build(const mjModel* m, const Muscle* mu) {
  int* index = (int*)malloc(sizeof(int) * (size_t)m->nbody);  // body -> link index, or -1
  if (!index) {
    return NULL;
  }
  for (int b = 0; b < m->nbody; b++) {
    index[b] = -1;
  }
  int nseg = mu->nactuator * mu->segments, nlink = 0;
  char why[200];
  ArcSegment seg;
  for (int k = 0; k < mu->nactuator; k++) {  // mark the links (and their proximal links)
    int first = m->actuator_trnid[2 * mu->actuator[k]] + 1;
    for (int s = 0; s < mu->segments; s++) {
      int hx, hy;
      for (int b = arc_segment_of(m, first + s, &seg, why, sizeof(why)); b > 0; b = m->body_parentid[b]) {
        int kind = link_kind(m, b, &hx, &hy);
        if (kind < 0) {
          break;
        }
        if (kind == 1 && index[b] < 0) {
          index[b] = 0;
          nlink++;
        }
      }
    }
  }
  ArcGeometry* g = arc_alloc(nlink, nseg);
  if (!g) {
    free(index);
    return NULL;
  }
  int n = 0;
  for (int b = 1; b < m->nbody; b++) {
    if (index[b] < 0) {
      continue;
    }
    int hx = -1, hy = -1;
    link_kind(m, b, &hx, &hy);
    ArcLink* L = &g->link[n];
    L->qpos_a = m->jnt_qposadr[hx];
    L->qpos_b = m->jnt_qposadr[hy];
    L->dof_a = m->jnt_dofadr[hx];
    L->dof_b = m->jnt_dofadr[hy];
    L->x_first = hx < hy;  // joints of a body apply in order
    L->parent = -1;
    for (int p = m->body_parentid[b]; p > 0; p = m->body_parentid[p]) {
      int px, py, kind = link_kind(m, p, &px, &py);
      if (kind < 0) {
        break;
      }
      if (kind == 1) {
        L->parent = index[p];  // parents come first: already numbered
        break;
      }
    }
    index[b] = n++;
  }
  n = 0;
  for (int k = 0; k < mu->nactuator; k++) {
    int first = m->actuator_trnid[2 * mu->actuator[k]] + 1;
    for (int s = 0; s < mu->segments; s++) {
      int node = arc_segment_of(m, first + s, &g->seg[n], why, sizeof(why));
      g->seg[n++].link = index[node];
    }
  }
  free(index);
  return g;
}

// The series of phi(t), v(t) = phi'(t) / sin t, s(t) = t / sin t, w(t) = s'(t) / sin t in t^2 up to
// t^12 (below ARC_SERIES_BELOW; the next terms are below 1e-16 there), the closed forms above it
// (where their cancellation costs less than 1e-14).
#define ARC_SERIES_BELOW 0.25

static double arc_poly(const double* c, double t2) {
  double p = c[6];
  for (int k = 5; k >= 0; k--) {
    p = p * t2 + c[k];
  }
  return p;
}

typedef struct {
  double theta, phi, v, s, w;
} ArcAngle;

static ArcAngle arc_angle(double sin_theta, double cos_theta) {
  static const double kPhi[7] = {1.0, -1.0 / 12, -1.0 / 720, -1.0 / 30240, -1.0 / 1209600, -1.0 / 47900160,
                                 -691.0 / 1307674368000.0};
  static const double kV[7] = {-1.0 / 6, -1.0 / 30, -11.0 / 2520, -37.0 / 75600, -49.0 / 950400,
                               -288731.0 / 54486432000.0, -352823.0 / 653837184000.0};
  static const double kS[7] = {1.0, 1.0 / 6, 7.0 / 360, 31.0 / 15120, 127.0 / 604800, 73.0 / 3421440,
                               1414477.0 / 653837184000.0};
  static const double kW[7] = {1.0 / 3, 2.0 / 15, 2.0 / 63, 4.0 / 675, 2.0 / 2079, 2764.0 / 19348875,
                               4.0 / 200475};
  ArcAngle r;
  double t = atan2(sin_theta, cos_theta);  // in [0, pi]
  r.theta = t;
  if (t < ARC_SERIES_BELOW) {
    double t2 = t * t;
    r.phi = arc_poly(kPhi, t2);
    r.v = arc_poly(kV, t2);
    r.s = arc_poly(kS, t2);
    r.w = arc_poly(kW, t2);
    return r;
  }
  double sin_half = sin(0.5 * t);
  r.phi = 0.5 * t * cos(0.5 * t) / sin_half;
  r.v = (sin_theta - t) / (4.0 * sin_half * sin_half * sin_theta);
  r.s = t / sin_theta;
  r.w = (sin_theta - t * cos_theta) / (sin_theta * sin_theta * sin_theta);
  return r;
}

// Beyond ARC_EXACT_UP_TO rad of bend in one link (115 deg: a section at D disks bends up to
// D x that exactly) a segment blends into the linear geometry l = e + (y' a - x' b) / 2 (and
// the link's twist to 0), fully at ARC_LINEAR_FROM: the swing is singular at theta = pi (its
// direction is undefined, the tangent length e no longer changes the arc, tan(theta/2)
// diverges), and a link bent that far is far outside the muscles' admissible lengths anyway.
// The blend weight is C2 in theta, so the segment lengths stay smooth and the forces
// conservative.
#define ARC_EXACT_UP_TO 2.0
#define ARC_LINEAR_FROM 2.5

// Per link: its swing (sigma, and the pieces of its derivatives), its twist and derivatives,
// the blend weight.
typedef struct {
  double a, b;
  double phi, v, s, w;
  double sigma[2], u[2], du_da[2], du_db[2];
  double theta_a, theta_b;  // sin a cos b and cos a sin b: d theta / d(a, b) times sin theta
  double tau, tau_a, tau_b; // the link's twist, blended
  double weight, weight_a, weight_b;  // 1: arc geometry, 0: linear; its derivatives in (a, b)
  double twist_before;      // T: the twists of the proximal links
  double cos_T, sin_T;      // of T, once per link (not per muscle segment)
} ArcLinkState;

static void arc_link_state(const ArcLink* L, const mjtNum* qpos, ArcLinkState* st) {
  double a = qpos[L->qpos_a], b = qpos[L->qpos_b];
  double sa = sin(a), ca = cos(a), sb = sin(b), cb = cos(b);
  st->a = a;
  st->b = b;
  if (L->x_first) {  // Q z = (sin b, -sin a cos b, cos a cos b)
    st->u[0] = sa * cb;
    st->u[1] = sb;
    st->du_da[0] = ca * cb;
    st->du_da[1] = 0.0;
    st->du_db[0] = -sa * sb;
    st->du_db[1] = cb;
  } else {  // Q z = (cos a sin b, -sin a, cos a cos b)
    st->u[0] = sa;
    st->u[1] = ca * sb;
    st->du_da[0] = ca;
    st->du_da[1] = -sa * sb;
    st->du_db[0] = 0.0;
    st->du_db[1] = ca * cb;
  }
  st->theta_a = sa * cb;
  st->theta_b = ca * sb;
  double sin_theta = sqrt(st->u[0] * st->u[0] + st->u[1] * st->u[1]);
  double theta = atan2(sin_theta, ca * cb);
  st->weight = 1.0;
  st->weight_a = st->weight_b = 0.0;
  if (theta >= ARC_LINEAR_FROM) {
    st->weight = 0.0;
  } else if (theta > ARC_EXACT_UP_TO) {  // 1 - smootherstep(x), and its derivative along theta
    double width = ARC_LINEAR_FROM - ARC_EXACT_UP_TO, x = (theta - ARC_EXACT_UP_TO) / width;
    st->weight = 1.0 - x * x * x * (x * (6.0 * x - 15.0) + 10.0);
    double slope = -30.0 * x * x * (1.0 - x) * (1.0 - x) / width / sin_theta;
    st->weight_a = slope * st->theta_a;
    st->weight_b = slope * st->theta_b;
  }
  st->tau = st->tau_a = st->tau_b = 0.0;
  st->phi = 1.0;
  st->v = st->s = st->w = 0.0;
  st->sigma[0] = st->sigma[1] = 0.0;
  if (st->weight == 0.0) {
    return;
  }
  ArcAngle ang = arc_angle(sin_theta, ca * cb);
  st->phi = ang.phi;
  st->v = ang.v;
  st->s = ang.s;
  st->w = ang.w;
  st->sigma[0] = ang.s * st->u[0];
  st->sigma[1] = ang.s * st->u[1];
  double sha = sin(0.5 * a), cha = cos(0.5 * a), shb = sin(0.5 * b), chb = cos(0.5 * b);
  double p = sha * shb, q = cha * chb, sign = L->x_first ? 1.0 : -1.0;
  double r2 = p * p + q * q;  // cos^2(theta / 2)
  double tau = sign * 2.0 * atan2(p, q);
  st->tau = st->weight * tau;
  st->tau_a = st->weight * sign * 0.5 * sb / r2 + st->weight_a * tau;
  st->tau_b = st->weight * sign * 0.5 * sa / r2 + st->weight_b * tau;
}

// Length of a segment and its derivatives (d/de, d/da, d/db, d/dT).
static double arc_segment_length(const ArcSegment* sg, const ArcLinkState* st, double e, double grad[4]) {
  double cT = st->cos_T, sT = st->sin_T;
  double x = cT * sg->x + sT * sg->y, y = -sT * sg->x + cT * sg->y;  // Rz(-T) (x, y)
  // the linear geometry (in the bundle's frame too)
  double linear = e + 0.5 * (y * st->a - x * st->b);
  double lin_grad[4] = {1.0, 0.5 * y, -0.5 * x, -0.5 * (x * st->a + y * st->b)};
  double W = st->weight;
  if (W == 0.0) {
    for (int c = 0; c < 4; c++) {
      grad[c] = lin_grad[c];
    }
    return linear;
  }
  double sigma_a[2], sigma_b[2];
  for (int c = 0; c < 2; c++) {
    sigma_a[c] = st->w * st->theta_a * st->u[c] + st->s * st->du_da[c];
    sigma_b[c] = st->w * st->theta_b * st->u[c] + st->s * st->du_db[c];
  }
  double arc = e * st->phi + 0.5 * (y * st->sigma[0] - x * st->sigma[1]);
  double arc_grad[4] = {
      st->phi,
      e * st->v * st->theta_a + 0.5 * (y * sigma_a[0] - x * sigma_a[1]),
      e * st->v * st->theta_b + 0.5 * (y * sigma_b[0] - x * sigma_b[1]),
      -0.5 * (x * st->sigma[0] + y * st->sigma[1]),
  };
  if (W == 1.0) {
    for (int c = 0; c < 4; c++) {
      grad[c] = arc_grad[c];
    }
    return arc;
  }
  for (int c = 0; c < 4; c++) {
    grad[c] = W * arc_grad[c] + (1.0 - W) * lin_grad[c];
  }
  grad[1] += st->weight_a * (arc - linear);
  grad[2] += st->weight_b * (arc - linear);
  return W * arc + (1.0 - W) * linear;
}

// The segments' forces push(P, N l) along the gradients of their arc lengths, minus the whole
// muscle's push(P, L) along the segments' fixed-tendon Jacobians (the actuator applies it).
static void add_arc_segment_forces(const mjModel* m, mjData* d, const Muscle* mu) {
  const ArcGeometry* g = mu->arc;
  const int N = mu->segments;
  mj_markStack(d);
  ArcLinkState* st = (ArcLinkState*)mj_stackAllocByte(d, sizeof(ArcLinkState) * (size_t)g->nlink,
                                                      _Alignof(ArcLinkState));
  mjtNum* pull = mj_stackAllocNum(d, 2 * (size_t)g->nlink);  // sum F dl/dT per link, then beyond it
  mjtNum* beyond = pull + g->nlink;
  mjtNum* pressure = mj_stackAllocNum(d, (size_t)g->nseg);
  mjtNum* length = mj_stackAllocNum(d, (size_t)g->nseg);
  mjtNum* tension = mj_stackAllocNum(d, (size_t)g->nseg);
  mjtNum* whole = mj_stackAllocNum(d, (size_t)g->nseg);
  mjtNum* grad = mj_stackAllocNum(d, 4 * (size_t)g->nseg);
  for (int k = 0; k < g->nlink; k++) {
    arc_link_state(&g->link[k], d->qpos, &st[k]);
    int p = g->link[k].parent;
    st[k].twist_before = p < 0 ? 0.0 : st[p].twist_before + st[p].tau;
    st[k].cos_T = cos(st[k].twist_before);
    st[k].sin_T = sin(st[k].twist_before);
    pull[k] = beyond[k] = 0.0;
  }
  for (int k = 0; k < mu->nactuator; k++) {
    int i = mu->actuator[k];
    double P = actuator_pressure(m, d, i);
    double whole_push = -muscle_tension(mu, P, d->actuator_length[m->actuator_outadr[i]]);
    for (int s = k * N; s < (k + 1) * N; s++) {
      const ArcSegment* sg = &g->seg[s];
      pressure[s] = P;
      whole[s] = whole_push;
      length[s] = N * arc_segment_length(sg, &st[sg->link], d->qpos[sg->slide_qpos], grad + 4 * s);
    }
  }
  for (int first = 0; first < g->nseg; first += BATCH) {
    int n = g->nseg - first < BATCH ? g->nseg - first : BATCH;
    tension_batch(mu, n, pressure + first, length + first, tension + first);
  }
  for (int k = 0; k < mu->nactuator; k++) {
    int first = m->actuator_trnid[2 * mu->actuator[k]] + 1;
    for (int s = k * N; s < (k + 1) * N; s++) {
      const ArcSegment* sg = &g->seg[s];
      const ArcLink* L = &g->link[sg->link];
      double F = -tension[s];
      d->qfrc_passive[sg->slide_dof] += F * grad[4 * s];
      d->qfrc_passive[L->dof_a] += F * grad[4 * s + 1];
      d->qfrc_passive[L->dof_b] += F * grad[4 * s + 2];
      pull[sg->link] += F * grad[4 * s + 3];
      int t = first + s - k * N, adr = m->ten_J_rowadr[t];
      for (int c = 0; c < m->ten_J_rownnz[t]; c++) {
        d->qfrc_passive[m->ten_J_colind[adr + c]] -= whole[s] * d->ten_J[adr + c];
      }
    }
  }
  // a link's twist turns every distal link's muscles: its hinges get the sum of their dl/dT
  for (int k = g->nlink - 1; k >= 0; k--) {
    int p = g->link[k].parent;
    if (p >= 0) {
      beyond[p] += beyond[k] + pull[k];
    }
    d->qfrc_passive[g->link[k].dof_a] += beyond[k] * st[k].tau_a;
    d->qfrc_passive[g->link[k].dof_b] += beyond[k] * st[k].tau_b;
  }
  mj_freeStack(d);
}

static int muscle_init(const mjModel* m, mjData* d, int instance) {
  init_data = d;  // a config error frees it (efam_fail): mj_initPlugin cannot, the error skips it
  init_instance = instance;
  Muscle* mu = muscle_create(m, instance);
  init_data = NULL;
  if (!mu) {
    mju_warning(PLUGIN_NAME ": out of memory");
    return -1;
  }
  d->plugin_data[instance] = (uintptr_t)mu;
  return 0;
}

static void muscle_destroy(mjData* d, int instance) {
  Muscle* mu = (Muscle*)d->plugin_data[instance];
  if (mu) {
    free(mu->arc);
  }
  free(mu);
  d->plugin_data[instance] = 0;
}

// mj_copyData keeps dest's own plugin_data (made by its init for the same model); the muscle
// constants are read-only, so copying them over is all a copy needs.
static void muscle_copy(mjData* dest, const mjModel* m, const mjData* src, int instance) {
  const Muscle* from = (const Muscle*)src->plugin_data[instance];
  Muscle* to = (Muscle*)dest->plugin_data[instance];
  if (!from || from == to) {
    return;
  }
  if (!to || to->nactuator != from->nactuator) {
    if (to) {
      free(to->arc);
    }
    free(to);
    to = (Muscle*)malloc(sizeof(Muscle) + sizeof(int) * (size_t)from->nactuator);
    dest->plugin_data[instance] = (uintptr_t)to;
    if (!to) {
      mju_error(PLUGIN_NAME ": out of memory copying mjData");
      return;
    }
    to->arc = NULL;
  }
  struct ArcGeometry* own = to->arc;  // dest's own copy of the (read-only) arc geometry
  memcpy(to, from, sizeof(Muscle) + sizeof(int) * (size_t)from->nactuator);
  to->arc = own;
  if (from->arc && !to->arc) {
    to->arc = arc_clone(from->arc);
    if (!to->arc) {
      mju_error(PLUGIN_NAME ": out of memory copying mjData");
    }
  }
}

// efam_effects.h: the effect terms' state (none when no effect is switched on)
static int muscle_nstate(const mjModel* m, int instance) { return effects_nstate(m, instance); }

static void muscle_reset(const mjModel* m, mjtNum* plugin_state, void* plugin_data, int instance) {
  effects_reset(m, plugin_state, instance);  // efam_effects.h
}

// ---------------------------------------------------------------------------- registration

// The MuJoCo header version this library was compiled against (the loader compares it with the
// MuJoCo it runs in).
EFAM_EXPORT int efam_muscle_mujoco_header_version(void) { return mjVERSION_HEADER; }

// Register efam.muscle with MuJoCo. Returns the plugin slot, or -1 when a different plugin of
// the same name is already registered (another copy of this library, e.g. one in MuJoCo's plugin
// directory: MuJoCo would abort on a second, non-identical registration, so we leave it be).
// Idempotent.
EFAM_EXPORT int efam_muscle_register(void) {
  int slot = -1;
  const mjpPlugin* existing = mjp_getPlugin(PLUGIN_NAME, &slot);
  if (existing) {
    return existing->compute == muscle_compute ? slot : -1;
  }
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = PLUGIN_NAME;
  // sensor: the pressures; passive: the segment forces of segmented muscles
  plugin.capabilityflags |= mjPLUGIN_ACTUATOR | mjPLUGIN_SENSOR | mjPLUGIN_PASSIVE;
  plugin.needstage = mjSTAGE_POS;
  plugin.nsensordata = muscle_nsensordata;
  // efam_effects.h: the muscle's keys, then `effects` and the effect parameter keys
  plugin.attributes = effects_all_attributes(kAttributes, NATTRIBUTE, &plugin.nattribute);
  plugin.nstate = muscle_nstate;
  plugin.init = muscle_init;
  plugin.destroy = muscle_destroy;
  plugin.copy = muscle_copy;
  plugin.reset = muscle_reset;
  plugin.advance = effects_advance;  // efam_effects.h: commits the effects' state once per step
  plugin.compute = muscle_compute;
  return mjp_registerPlugin(&plugin);
}

// The registry slot of efam.muscle, whichever library registered it; -1 when none did.
EFAM_EXPORT int efam_muscle_slot(void) {
  int slot = -1;
  return mjp_getPlugin(PLUGIN_NAME, &slot) ? slot : -1;
}

// 1 when the registered efam.muscle is this library's code, 0 when another copy registered it.
EFAM_EXPORT int efam_muscle_registered_here(void) {
  int slot = -1;
  const mjpPlugin* existing = mjp_getPlugin(PLUGIN_NAME, &slot);
  return existing && existing->compute == muscle_compute;
}

// Self-registration when the library is loaded, as MuJoCo expects of a plugin library: by
// mj_loadPluginLibrary / mj_loadAllPluginLibraries (C, simulate), by `import mujoco` when the
// library sits in MuJoCo's plugin directory (Python, dm_control, `python -m mujoco.viewer`), and
// by `import efam_mujoco`. Under another MuJoCo minor version the structs may differ: register
// nothing then (efam_mujoco's loader reports the mismatch; the library is linked to the
// libmujoco it was built against, so this only happens with a relinked or preloaded MuJoCo).
mjPLUGIN_LIB_INIT(efam_muscle) {
  if (mj_version() / 1000 == mjVERSION_HEADER / 1000) {
    efam_muscle_register();
  }
}
