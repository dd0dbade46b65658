// efam_effects.h: the diagnosis's effect terms (efam_mujoco/diagnose/effects.py) switched on
// inside the efam.muscle plugin. Included once by efam_muscle.c, after its stress-law table and
// before its Muscle struct, which holds an EffectsConfig.
//
// The reference is EffectModel.push_stepwise / Effect.step: every term below is evaluated from
// the same inputs, in the same order, with the same constants, so a MuJoCo replay of a recording
// equals push_stepwise to about 1e-12 relative (tests/test_plugin_effects.py holds it to 1e-9).
// The terms need Eq. 2 in forms the muscle's batched hot path does not compute (at a stretched
// thread, the bladder share alone, at other pressures and lengths), so this file keeps its own
// scalar Eq. 2, evaluated as muscle.py and effects.py do, from a copy of the muscle's constants.
// Nothing here runs unless config key `effects` names at least one term.
//
// Config keys: `effects` = comma-separated names (friction, viscoelasticity, end_effects,
// braid_compliance, softening, drift, pressure_lag); each parameter is `<effect>.<key>` with the
// key (unit in it) and bounds of effects.py, e.g. `friction.f0_N`, `viscoelasticity.tau_s`.
// force_offset is a load-cell zero error, not an actuator force: the rig adds it to its reading.
// pressure_lag's first-order lag is MuJoCo's own: the actuator must have dyntype="filterexact"
// dynprm="<tau_s>" actdim="1" (actearly="true" to match push_stepwise sample for sample); the
// plugin adds the gas-volume term on top of it.
//
// State, in MuJoCo's plugin state (mjData.plugin_state: one per mjData, copied by mj_copyData,
// zeroed by mj_resetData, so thread-safe with no locks): per actuator one block of doubles,
// [started, t_first, t_prev, L_prev, P_prev, the effects' own states in config order]. The
// instance holds the committed blocks, then the pending blocks, then [pending_valid,
// pending_time]. compute evaluates the terms from the committed state and writes what the state
// becomes into the pending blocks; advance (once per mj_step, after integration) commits them.
// Extra mj_forward calls (sensors, viewers, a changed control before the step) only rewrite the
// pending blocks, so the state advances exactly once per mj_step. With the RK4 integrator the
// pending state of the step's first evaluation (the earliest time) is kept, not that of the
// intermediate stages.
//
// Inputs the terms see, per actuator: L = actuator_length, P = the pressure the muscle sees
// (ctrl, or the filtered pressure in the activation) -- with pressure_lag switched on, P is the
// measured pressure (the clamped ctrl) and the activation is the lagged one, as in effects.py --
// t = d->time - t_first, dt = d->time - t_prev (a clock that goes back counts as no time).
// A non-finite input, force or state adds nothing and leaves the state where it was.

#define NEFFECT_PARAM_MAX 6
#define EFFECT_HEADER_STATE 5  // started, t_first, t_prev, L_prev, P_prev
#define EFFECT_P_ATM 101325.0  // effects.P_ATM

typedef enum {
  FX_FRICTION,
  FX_VISCOELASTICITY,
  FX_END_EFFECTS,
  FX_BRAID_COMPLIANCE,
  FX_SOFTENING,
  FX_DRIFT,
  FX_PRESSURE_LAG,
  NEFFECT
} EffectKind;

typedef struct {
  const char* key;
  double lo, hi;  // inclusive, as effects.Param / check_values
  int optional;    // may be absent, as effects.Param.default: a key added after files were written
  double fallback;  // its value when absent (effects.Param.default)
  int discrete;     // a mode: only the integers lo, lo + 1, ..., hi (effects.Param.discrete, its grid)
} EffectParam;

typedef struct {
  const char* name;
  int nparam;
  EffectParam params[NEFFECT_PARAM_MAX];
  int nstate;  // doubles of its own per actuator
} EffectSpec;

// effects.LIBRARY without force_offset, parameters in its order (the step functions index them).
static const EffectSpec kEffects[NEFFECT] = {
    {"friction",
     6,
     {{"f0_N", 0.0, 100.0},
      {"f1_N_per_MPa", 0.0, 300.0},
      {"slip_strain", 5e-4, 0.05},
      {"slip_kPa", 0.0, 1e4},
      {"relax_per_s", 0.0, 10.0, 1, 0.0},
      {"smooth", 0.0, 1.0, 1, 0.0, 1}},
     1},
    {"viscoelasticity",
     5,
     {{"k0_N", 0.0, 5000.0},
      {"k1_N_per_MPa", 0.0, 10000.0},
      {"g_bladder", 0.0, 1.0, 1, 0.0},
      {"tau_s", 0.1, 500.0},
      {"g_slow_bladder", 0.0, 1.0, 1, 0.0}},
     3},
    {"end_effects", 3, {{"kappa0", 0.0, 0.5}, {"kappa1", -0.5, 0.5}, {"P_e_kPa", 10.0, 1000.0}}, 0},
    {"braid_compliance", 2, {{"b1_per_MPa", 0.0, 0.2}, {"b2_per_MPa2", -0.2, 0.2}}, 0},
    {"softening", 2, {{"a", 0.0, 1.0}, {"width", 1e-3, 0.5}}, 1},
    {"drift",
     6,
     {{"d0_N_per_s", -1.0, 1.0},
      {"d1_N_per_s", -10.0, 10.0},
      {"d2_N_per_s_MPa", -10.0, 10.0},
      {"tau_s", 10.0, 1e6},
      {"clock", 0.0, 1.0, 1, 0.0, 1},
      {"course", -1.0, 1.0, 1, 1.0, 1}},
     1},
    {"pressure_lag", 3, {{"tau_s", 0.002, 3.0}, {"delay_s", 0.0, 0.5, 1, 0.0}, {"volume_gain", 0.0, 1.5, 1, 1.0}}, 2},
};
#define EFFECT_KNOWN "friction, viscoelasticity, end_effects, braid_compliance, softening, drift, pressure_lag"

// The muscle's constants the terms need (a copy: see the top of the file).
typedef struct {
  double rest_length, bladder_volume, deadband, lock_stiffness;
  int tension_only;
  Law law;
  double coef[4], arccot_scale;
  double turns, thread, thread_sq_pow, min_length, max_length, rest_outer_radius, rest_wall, rest_mid_radius;
} EffectsMuscle;

// The constants of a Muscle `mu` (expanded where the Muscle struct is complete).
#define EFFECTS_MUSCLE_OF(mu)                                                                        \
  ((EffectsMuscle){.rest_length = (mu).rest_length, .bladder_volume = (mu).bladder_volume,           \
                   .deadband = (mu).deadband, .lock_stiffness = (mu).lock_stiffness,                 \
                   .tension_only = (mu).tension_only, .law = (mu).law,                               \
                   .coef = {(mu).coef[0], (mu).coef[1], (mu).coef[2], (mu).coef[3]},                 \
                   .arccot_scale = (mu).arccot_scale, .turns = (mu).turns, .thread = (mu).thread,    \
                   .thread_sq_pow = (mu).thread_sq_pow, .min_length = (mu).min_length,               \
                   .max_length = (mu).max_length, .rest_outer_radius = (mu).rest_outer_radius,       \
                   .rest_wall = (mu).rest_wall, .rest_mid_radius = (mu).rest_mid_radius})

typedef struct {
  int count;                                   // effects switched on; 0: the plugin as without them
  EffectKind kind[NEFFECT];                    // in the order of config key `effects`
  double value[NEFFECT][NEFFECT_PARAM_MAX];    // their parameters, in kEffects order
  int state_offset[NEFFECT];                   // of each one's own state inside an actuator block
  int block;                                   // doubles per actuator
  int pressure_lag;                            // switched on: the effects see the measured pressure
  EffectsMuscle muscle;
} EffectsConfig;

// Defined in efam_muscle.c (after the Muscle struct, which needs this file first).
static double actuator_pressure(const mjModel* m, const mjData* d, int i);
static double transducer_pressure(const mjModel* m, const mjData* d, int i);
static const char* instance_label(const mjModel* m, int instance, char* buf, size_t size);
static const char* config_value(const mjModel* m, int instance, const char* key);
static double read_number(const mjModel* m, int instance, const char* key, int required, double fallback);

#define EFFECT_ERROR(m, instance, fmt, ...)                                                    \
  do {                                                                                         \
    char label_[160];                                                                          \
    mju_error("efam.muscle (%s): " fmt, instance_label(m, instance, label_, sizeof(label_)), \
              __VA_ARGS__);                                                                    \
  } while (0)

// ------------------------------------------------------------------------------ config keys

#define NEFFECT_ATTRIBUTE_MAX (1 + NEFFECT * NEFFECT_PARAM_MAX)
#define EFFECT_KEY_SIZE 48

// "<effect>.<key>" of parameter j of effect e.
static void effect_key(EffectKind e, int j, char* out) {
  snprintf(out, EFFECT_KEY_SIZE, "%s.%s", kEffects[e].name, kEffects[e].params[j].key);
}

// The muscle's own config keys followed by `effects` and every effect parameter key, for
// mjpPlugin.attributes (built once, at registration; MuJoCo copies the names).
static const char* const* effects_all_attributes(const char* const* muscle_keys, int nmuscle, int* total) {
  static char keys[NEFFECT_ATTRIBUTE_MAX][EFFECT_KEY_SIZE];
  static const char* all[64 + NEFFECT_ATTRIBUTE_MAX];
  int n = 0;
  for (int a = 0; a < nmuscle && a < 64; a++) {
    all[n++] = muscle_keys[a];
  }
  all[n++] = "effects";
  int k = 0;
  for (int e = 0; e < NEFFECT; e++) {
    for (int j = 0; j < kEffects[e].nparam; j++, k++) {
      effect_key((EffectKind)e, j, keys[k]);
      all[n++] = keys[k];
    }
  }
  *total = n;
  return all;
}

// Calls visit(kind, context) for each name in config key `effects`; a name that is not an
// actuator-force effect gives kind = NEFFECT. Returns -1 for an empty name, else 0.
static int effects_each_name(const char* list, void (*visit)(EffectKind, const char*, int, void*), void* context) {
  const char* p = list;
  while (p && *p) {
    while (*p == ' ' || *p == '\t') {
      p++;
    }
    const char* end = p;
    while (*end && *end != ',') {
      end++;
    }
    int len = (int)(end - p);
    while (len > 0 && (p[len - 1] == ' ' || p[len - 1] == '\t')) {
      len--;
    }
    if (len == 0) {
      return -1;
    }
    EffectKind kind = NEFFECT;
    for (int e = 0; e < NEFFECT; e++) {
      if ((int)strlen(kEffects[e].name) == len && strncmp(kEffects[e].name, p, (size_t)len) == 0) {
        kind = (EffectKind)e;
      }
    }
    visit(kind, p, len, context);
    p = *end ? end + 1 : end;
  }
  return 0;
}

static void count_state(EffectKind kind, const char* name, int len, void* context) {
  if (kind != NEFFECT) {
    *(int*)context += kEffects[kind].nstate;
  }
}

// Doubles per actuator for config key `effects` (0 when none is named). Lenient: init rejects
// what is wrong, with a message.
static int effects_block(const mjModel* m, int instance) {
  const char* list = config_value(m, instance, "effects");
  int block = 0, named = 0;
  if (!list) {
    return 0;
  }
  for (const char* p = list; *p; p++) {
    named |= *p != ' ' && *p != '\t';  // "," is named (and rejected): an empty name
  }
  if (!named) {
    return 0;
  }
  effects_each_name(list, count_state, &block);
  return EFFECT_HEADER_STATE + block;
}

// mjpPlugin.nstate: committed and pending blocks for every actuator of the instance, and the
// pending flag and time. Called by the compiler once actuator_plugin and the config are set.
static int effects_nstate(const mjModel* m, int instance) {
  int block = effects_block(m, instance);
  int nact = 0;
  for (int i = 0; i < m->nactuator; i++) {
    nact += m->actuator_plugin[i] == instance;
  }
  return block && nact ? 2 * nact * block + 2 : 0;
}

typedef struct {
  const mjModel* m;
  int instance;
  EffectsConfig* fx;
} ParseContext;

static void add_effect(EffectKind kind, const char* name, int len, void* context) {
  ParseContext* c = (ParseContext*)context;
  if (kind == NEFFECT) {
    if (len == 12 && strncmp(name, "force_offset", 12) == 0) {
      EFFECT_ERROR(c->m, c->instance,
                   "config key 'effects': 'force_offset' is a load-cell zero error, not an actuator "
                   "force; add it to the load-cell reading (efam_mujoco.rig does)%s",
                   "");
    }
    EFFECT_ERROR(c->m, c->instance, "config key 'effects': unknown effect '%.*s' (known: %s)", len, name,
                 EFFECT_KNOWN);
  }
  for (int k = 0; k < c->fx->count; k++) {
    if (c->fx->kind[k] == kind) {
      EFFECT_ERROR(c->m, c->instance, "config key 'effects': effect '%s' is named twice", kEffects[kind].name);
    }
  }
  c->fx->kind[c->fx->count++] = kind;
}

static int effect_on(const EffectsConfig* fx, EffectKind kind) {
  for (int k = 0; k < fx->count; k++) {
    if (fx->kind[k] == kind) {
      return 1;
    }
  }
  return 0;
}

// pressure_lag rides on the actuator's own first-order lag (filterexact with the same tau) and on
// MuJoCo's own ctrl delay for the line's transport delay (the same delay, linearly interpolated).
static void check_pressure_lag(const mjModel* m, int instance, double tau, double delay) {
  for (int i = 0; i < m->nactuator; i++) {
    if (m->actuator_plugin[i] != instance) {
      continue;
    }
    double given = m->actuator_delay[i];
    int linear = m->actuator_history[2 * i + 1] == 1;
    if (!(fabs(given - delay) <= 1e-12 * (delay > 1e-3 ? delay : 1e-3)) || (delay > 0 && !linear)) {
      EFFECT_ERROR(m, instance,
                   "config key 'pressure_lag.delay_s' = %.10g needs the actuator's own ctrl delay with the "
                   "same value: delay=\"%.17g\" nsample=\"N\" interp=\"linear\" (N samples spanning the delay); "
                   "the actuator has delay %.10g%s",
                   delay, delay, given, delay > 0 && !linear ? " without interp=\"linear\"" : "");
    }
    double dynprm = m->actuator_dynprm[i * mjNDYN];
    if (m->actuator_dyntype[i] != mjDYN_FILTEREXACT || !(fabs(dynprm - tau) <= 1e-12 * tau)) {
      EFFECT_ERROR(m, instance,
                   "config key 'pressure_lag.tau_s' = %.10g needs the actuator's own lag with the same "
                   "time constant: dyntype=\"filterexact\" dynprm=\"%.17g\" actdim=\"1\" (actearly=\"true\" "
                   "to match push_stepwise); the actuator has dyntype %d, dynprm %.10g",
                   tau, tau, m->actuator_dyntype[i], dynprm);
    }
  }
}

// Read and validate the effect keys (an error names the key); the muscle's constants are copied.
static void effects_configure(const mjModel* m, int instance, EffectsConfig* fx, EffectsMuscle muscle) {
  memset(fx, 0, sizeof(*fx));
  fx->muscle = muscle;
  const char* list = config_value(m, instance, "effects");
  if (list && effects_block(m, instance)) {
    ParseContext context = {m, instance, fx};
    if (effects_each_name(list, add_effect, &context) < 0) {
      EFFECT_ERROR(m, instance, "config key 'effects' = '%s' has an empty name (comma-separated names: %s)",
                   list, EFFECT_KNOWN);
    }
  }
  char key[EFFECT_KEY_SIZE];
  for (int e = 0; e < NEFFECT; e++) {
    int on = effect_on(fx, (EffectKind)e);
    for (int j = 0; j < kEffects[e].nparam; j++) {
      effect_key((EffectKind)e, j, key);
      if (!on) {
        if (config_value(m, instance, key)) {
          EFFECT_ERROR(m, instance, "config key '%s' is given but effect '%s' is not in config key 'effects'",
                       key, kEffects[e].name);
        }
        continue;
      }
      const EffectParam* p = &kEffects[e].params[j];
      double value = read_number(m, instance, key, !p->optional, p->fallback);
      if (!(p->lo <= value && value <= p->hi)) {
        EFFECT_ERROR(m, instance, "config key '%s' = %.10g is outside [%g, %g]", key, value, p->lo, p->hi);
      }
      if (p->discrete && value != floor(value)) {
        char modes[64] = "";  // "0, 1" or "-1, 0, 1": the modes are the integers lo..hi
        for (int mode = (int)p->lo; mode <= (int)p->hi; mode++) {
          size_t used = strlen(modes);
          snprintf(modes + used, sizeof(modes) - used, mode > (int)p->lo ? ", %d" : "%d", mode);
        }
        EFFECT_ERROR(m, instance, "config key '%s' = %.10g is not one of %s", key, value, modes);
      }
      fx->value[e][j] = value;
    }
  }
  fx->block = fx->count ? EFFECT_HEADER_STATE : 0;
  for (int k = 0; k < fx->count; k++) {
    fx->state_offset[fx->kind[k]] = fx->block;
    fx->block += kEffects[fx->kind[k]].nstate;
  }
  fx->pressure_lag = effect_on(fx, FX_PRESSURE_LAG);
  if (fx->pressure_lag) {
    check_pressure_lag(m, instance, fx->value[FX_PRESSURE_LAG][0], fx->value[FX_PRESSURE_LAG][1]);
  }
  int expected = effects_nstate(m, instance);
  if (m->plugin_statenum[instance] != expected) {  // nstate and init read the same keys: cannot happen
    EFFECT_ERROR(m, instance, "plugin state has %d doubles, the effects need %d", m->plugin_statenum[instance],
                 expected);
  }
}

// ------------------------------------------------------------------ Eq. 2, as effects.py uses it

// StressLaw.__call__ (law_stress in efam_muscle.c)
static double fx_stress(const EffectsMuscle* k, double e, double P) {
  return law_stress(k->law, k->coef, k->arccot_scale, e, P);
}

// Muscle.outer_radius (Eq. 10) at a length as given (not clipped).
static double fx_outer_radius(const EffectsMuscle* k, double L) {
  return sqrt(max0(k->thread_sq_pow - L * L)) / (2 * M_PI * k->turns);
}

// Eq. 11 (Muscle._wall)
static double fx_wall(const EffectsMuscle* k, double L, double r_out) { return wall(k->bladder_volume, L, r_out); }

// The bladder's two stress terms of Eq. 2 at a clipped length (effects.bladder_tension).
static double fx_bladder_terms(const EffectsMuscle* k, double P, double L, double r_out, double t) {
  double N = k->turns;
  double eps_z = L / k->rest_length - 1.0;
  double eps_c = (r_out - t / 2) / k->rest_mid_radius - 1.0;
  return fx_stress(k, eps_z, P) * k->bladder_volume / L -
         fx_stress(k, eps_c, P) * t * L * L / (2 * M_PI * r_out * N * N);
}

// Muscle.tension: Eq. 2 with the lock-out spring, tension-only, zero for non-finite inputs.
static double fx_tension(const EffectsMuscle* k, double pressure, double length) {
  if (!isfinite(pressure) || !isfinite(length)) {
    return 0.0;
  }
  double P = max0(pressure);
  double L = clip(length, k->min_length, k->max_length);
  double r_out = fx_outer_radius(k, L);
  double t = fx_wall(k, L, r_out);
  double gauge = max0(P - k->deadband);
  double N = k->turns;
  double force = gauge / (4 * M_PI * N * N) * (3 * L * L - k->thread * k->thread) +
                 fx_bladder_terms(k, P, L, r_out, t);
  force = force + k->lock_stiffness * (length - L);
  if (k->tension_only) {
    force = max0(force);
  }
  return force;
}

static double fx_push(const EffectsMuscle* k, double P, double L) { return -fx_tension(k, P, L); }

// effects.tension_with_thread: Eq. 2 with the thread length scaled (no lock-out, not one-sided).
static double fx_tension_with_thread(const EffectsMuscle* k, double pressure, double length, double scale) {
  double P = max0(pressure);
  double L = clip(length, k->min_length, k->max_length);
  double B = k->thread * scale;
  double N = k->turns;
  double r_out = sqrt(max0(B * B - L * L)) / (2 * M_PI * N);
  double t = fx_wall(k, L, r_out);
  double gauge = max0(P - k->deadband);
  return gauge / (4 * M_PI * N * N) * (3 * L * L - B * B) + fx_bladder_terms(k, P, L, r_out, t);
}

// effects.bladder_tension
static double fx_bladder_tension(const EffectsMuscle* k, double pressure, double length) {
  double L = clip(length, k->min_length, k->max_length);
  double r_out = fx_outer_radius(k, L);
  return fx_bladder_terms(k, max0(pressure), L, r_out, fx_wall(k, L, r_out));
}

// effects.gas_volume: pi R_o(L)^2 L - V_B, at least 1e-9 m^3.
static double fx_gas_volume(const EffectsMuscle* k, double length) {
  double L = clip(length, k->min_length, k->max_length);
  double r_out = fx_outer_radius(k, L);
  double V = M_PI * libm_pow(r_out, 2) * L - k->bladder_volume;
  return V > 1e-9 ? V : 1e-9;
}

// --------------------------------------------------------------------------- the terms

typedef struct {
  double t, dt, P, L, P_prev, L_prev, x;
  double P_seen, base;  // what the muscle's own force used, and that force (push sign)
  int first, engaged;
} EffectSample;

static double fx_clip1(double z) { return z > 1.0 ? 1.0 : (z < -1.0 ? -1.0 : z); }

// effects.dahl_step: Dahl's state after a slip du (in widths), dz/du = 1 - z sign(du) integrated
// exactly over the step.
static double fx_dahl(double z, double du) {
  if (du > 0.0) return 1.0 - (1.0 - z) * exp(-du);
  if (du < 0.0) return -1.0 + (1.0 + z) * exp(du);
  return z;
}

// Friction.step: one play operator (smooth 1: Dahl's) on the slip that the strain and the
// pressure both drive, relaxing at relax_per_s; slip_kPa 0: pressure slides nothing.
static double friction_step(const EffectsMuscle* k, const double* v, double* z, const EffectSample* s) {
  if (s->first) {
    z[0] = 0.0;
  }
  double slip = (s->L - s->L_prev) / k->rest_length / v[2];
  if (v[3] > 0) {
    double sign_now = -copysign(1.0, 3 * libm_pow(s->L, 2) - k->thread_sq_pow);
    double sign_prev = -copysign(1.0, 3 * libm_pow(s->L_prev, 2) - k->thread_sq_pow);
    slip += (sign_now * s->P - sign_prev * s->P_prev) / (v[3] * 1e3);
  }
  double kept = z[0] * exp(-v[4] * s->dt);
  z[0] = v[5] == 1.0 ? fx_dahl(kept, slip) : fx_clip1(kept + slip);
  double force = -(v[0] + v[1] * s->P / 1e6) * z[0];
  return s->engaged ? force : 0.0;
}

// Viscoelasticity.SLOW_RATIO and SLOW_MAX_S: the slow bladder branch's relaxation time.
#define FX_VISCO_SLOW_RATIO 20.0
#define FX_VISCO_SLOW_MAX_S 1000.0

// Viscoelasticity.step: Maxwell branches on the strain and on the bladder's force (a fast and a
// slow one).
static double viscoelasticity_step(const EffectsMuscle* k, const double* v, double* w, const EffectSample* s) {
  double bladder = -fx_bladder_tension(k, s->P, s->L);
  if (s->first) {
    w[0] = s->x;
    w[1] = bladder;
    w[2] = bladder;
  } else {
    double a = 1.0 - exp(-s->dt / v[3]);
    double tau_slow = fmin(FX_VISCO_SLOW_RATIO * v[3], FX_VISCO_SLOW_MAX_S);
    double a_slow = 1.0 - exp(-s->dt / tau_slow);
    w[0] += a * (s->x - w[0]);
    w[1] += a * (bladder - w[1]);
    w[2] += a_slow * (bladder - w[2]);
  }
  double force = -(v[0] + v[1] * s->P / 1e6) * (s->x - w[0]);
  force += v[2] * (bladder - w[1]);
  force += v[4] * (bladder - w[2]);
  return s->engaged ? force : 0.0;
}

// EndEffects.step: Tondu's strain factor times the model's stiffness dF/dL.
static double end_effects_step(const EffectsMuscle* k, const double* v, const EffectSample* s) {
  double h = 1e-6 * k->rest_length;
  double slope = (fx_push(k, s->P, s->L + h) - fx_push(k, s->P, s->L - h)) / (2 * h);
  double kappa = v[0] + v[1] * exp(-s->P / (v[2] * 1e3));
  double force = kappa * (s->L - k->rest_length) * slope;
  return s->engaged ? force : 0.0;
}

// BraidCompliance.step: thread strain b1 q + b2 q^2 times the push force's change per thread
// stretch, a secant over a 1 % longer thread (effects.braid_slope: the tangent is unbounded at the
// resting length under the exponent law).
#define THREAD_SECANT 0.01
static double braid_compliance_step(const EffectsMuscle* k, const double* v, const EffectSample* s) {
  double load = s->P - k->deadband;
  double q = (load > 0.0 ? load : 0.0) / 1e6 * fx_outer_radius(k, s->L) / k->rest_outer_radius;
  double slope = -(fx_tension_with_thread(k, s->P, s->L, 1 + THREAD_SECANT) - fx_tension_with_thread(k, s->P, s->L, 1)) /
                 THREAD_SECANT;
  double force = (v[0] * q + v[1] * q * q) * slope;
  return s->engaged ? force : 0.0;
}

// Softening.step: the bladder share, stiffer near the largest u so far.
static double softening_step(const EffectsMuscle* k, const double* v, double* m, const EffectSample* s) {
  double u = fabs(s->x) * (1.0 + s->P / 0.5e6);
  m[0] = s->first ? u : (m[0] >= u ? m[0] : u);
  double bladder = -fx_bladder_tension(k, s->P, s->L);
  double force = v[0] * exp(-(m[0] - u) / v[1]) * bladder;
  return s->engaged ? force : 0.0;
}

// Drift.step: (d0 + d1 x + d2 P_MPa) s(u); u = the time since the start (clock 0) or the time under
// pressure, the sum of P_MPa dt (clock 1, state u[0]); s saturating (course 1), accelerating (-1)
// or logarithmic (0): tau (1 - exp(-u/tau)), tau (exp(u/tau) - 1), tau log(1 + u/tau).
static double drift_step(const double* v, double* u, const EffectSample* s) {
  u[0] = s->first ? 0.0 : u[0] + max0(s->P) / 1e6 * s->dt;
  double tau = v[3];
  double clock = v[4] == 1.0 ? u[0] : s->t;
  double ramp = v[5] == -1.0  ? tau * expm1(clock / tau)
                : v[5] == 0.0 ? tau * log1p(clock / tau)
                              : tau * -expm1(-clock / tau);
  double force = (v[0] + v[1] * s->x + v[2] * s->P / 1e6) * ramp;
  return s->engaged ? force : 0.0;
}

// PressureLag.step less the lag MuJoCo already applies: P_l = P_seen (the delayed, lagged control),
// G = lag(g) with g = tau (P + P_atm) dV/dt / V, and the volume term's force weighted by
// volume_gain k: F(P_seen) + k (F(P_seen - G) - F(P_seen)); y = G and V_prev are the state.
// Returns the change of the force the muscle's own evaluation (at P_seen) wrote.
static double pressure_lag_step(const EffectsMuscle* k, const double* v, double* y, const EffectSample* s) {
  double tau = v[0];
  double V = fx_gas_volume(k, s->L);
  if (s->first) {
    y[0] = 0.0;
    y[1] = V;
    return 0.0;
  }
  double g = tau * (s->P + EFFECT_P_ATM) * (V - y[1]) / (s->dt > 1e-12 ? s->dt : 1e-12) / V;
  y[0] += (1.0 - exp(-s->dt / tau)) * (g - y[0]);
  y[1] = V;
  if (!s->engaged) {
    return fx_push(k, s->P, s->L) - s->base;
  }
  double lagged = fx_push(k, s->P_seen, s->L);
  return lagged + v[2] * (fx_push(k, s->P_seen - y[0], s->L) - lagged) - s->base;
}

// The effects' force for one actuator; advances `state` (its block) by one sample.
static double effects_step(const EffectsConfig* fx, double* state, const EffectSample* s) {
  double force = 0.0;
  for (int n = 0; n < fx->count; n++) {
    EffectKind e = fx->kind[n];
    const double* v = fx->value[e];
    double* own = state + fx->state_offset[e];
    switch (e) {
      case FX_FRICTION:
        force += friction_step(&fx->muscle, v, own, s);
        break;
      case FX_VISCOELASTICITY:
        force += viscoelasticity_step(&fx->muscle, v, own, s);
        break;
      case FX_END_EFFECTS:
        force += end_effects_step(&fx->muscle, v, s);
        break;
      case FX_BRAID_COMPLIANCE:
        force += braid_compliance_step(&fx->muscle, v, s);
        break;
      case FX_SOFTENING:
        force += softening_step(&fx->muscle, v, own, s);
        break;
      case FX_DRIFT:
        force += drift_step(v, own, s);
        break;
      case FX_PRESSURE_LAG:
        force += pressure_lag_step(&fx->muscle, v, own, s);
        break;
      default:
        break;
    }
  }
  return force;
}


static int all_finite(const double* x, int n) {
  for (int i = 0; i < n; i++) {
    if (!isfinite(x[i])) {
      return 0;
    }
  }
  return 1;
}

// The compute hook: after the muscle's own forces are in d->actuator_force, add the effects'
// forces of every actuator of the instance, from the committed state; write the new state into
// the pending blocks (see the top of the file).
static void effects_add_forces(const mjModel* m, mjData* d, int instance, const EffectsConfig* fx,
                               const int* actuator, int nactuator) {
  int block = fx->block;
  if (!block || m->plugin_statenum[instance] != 2 * nactuator * block + 2) {
    return;
  }
  double* committed = d->plugin_state + m->plugin_stateadr[instance];
  double* pending = committed + nactuator * block;
  double* flag = pending + nactuator * block;  // [pending_valid, pending_time]
  int store = m->opt.integrator != mjINT_RK4 || flag[0] == 0.0 || d->time <= flag[1];
  double work[EFFECT_HEADER_STATE + 2 * NEFFECT];
  for (int k = 0; k < nactuator; k++) {
    int i = actuator[k];
    int out = m->actuator_outadr[i];
    const double* old = committed + k * block;
    memcpy(work, old, sizeof(double) * (size_t)block);
    EffectSample s;
    s.L = d->actuator_length[out];
    s.P_seen = actuator_pressure(m, d, i);
    s.P = fx->pressure_lag ? transducer_pressure(m, d, i) : s.P_seen;
    s.base = d->actuator_force[out];
    s.first = old[0] == 0.0;
    double t_first = s.first ? d->time : old[1];
    s.t = d->time - t_first;
    s.dt = s.first ? 0.0 : max0(d->time - old[2]);
    s.L_prev = s.first ? s.L : old[3];
    s.P_prev = s.first ? s.P : old[4];
    s.x = s.L / fx->muscle.rest_length - 1.0;
    if (!fx->muscle.tension_only) {
      s.engaged = 1;
    } else {  // effects.py: engaged where the model (at the measured pressure) is not slack
      s.engaged = (fx->pressure_lag ? fx_push(&fx->muscle, s.P, s.L) : s.base) != 0.0;
    }
    double force = 0.0;
    if (isfinite(s.L) && isfinite(s.P) && isfinite(s.P_seen)) {
      work[0] = 1.0;
      work[1] = t_first;
      work[2] = d->time;
      work[3] = s.L;
      work[4] = s.P;
      force = effects_step(fx, work, &s);
    }
    if (!isfinite(force) || !all_finite(work, block)) {
      force = 0.0;
      memcpy(work, old, sizeof(double) * (size_t)block);
    }
    d->actuator_force[out] = s.base + force;
    if (store) {
      memcpy(pending + k * block, work, sizeof(double) * (size_t)block);
    }
  }
  if (store) {
    flag[0] = 1.0;
    flag[1] = d->time;
  }
}

// mjpPlugin.advance: commit the pending state (once per mj_step, after integration).
static void effects_advance(const mjModel* m, mjData* d, int instance) {
  int n = m->plugin_statenum[instance];
  if (n < 2) {
    return;
  }
  double* state = d->plugin_state + m->plugin_stateadr[instance];
  int half = (n - 2) / 2;
  if (state[n - 2] != 0.0) {
    memcpy(state, state + half, sizeof(double) * (size_t)half);
    state[n - 2] = 0.0;
  }
}

// mjpPlugin.reset: nothing started (the first step initialises every state, as effects.py).
static void effects_reset(const mjModel* m, mjtNum* plugin_state, int instance) {
  int n = m->plugin_statenum[instance];
  for (int i = 0; i < n; i++) {
    plugin_state[i] = 0.0;
  }
}
