/* mbdk_fmi3.c - a scene as an FMI 3.0 co-simulation FMU: the binary of every FMU that
 * `mbdk fmu` (python/mbdk/fmu.py) exports. It holds no scene: an instance reads its scene's
 * tables and its variables from the FMU's resources folder, so one compiled library serves
 * every scene and no compiler is needed to export one.
 *
 *   resources/scene.tables.toml   the scene's kernel tables and assembled initial state
 *                                 (`mbdk tables`; read by mbdk_scene_tables_read)
 *   resources/fmu.txt             the run and the variables, one per line:
 *     mbdk-fmu 1                  the format
 *     index3 0|1                  an ODE method on a formulation, or the index-3 family
 *     opt ID FIELD VALUE          a field of an option struct as simulate sets it (ID as
 *                                 mbdk_struct_info: 2 mbdk_options, 3 mbdk_index3_options,
 *                                 4 mbdk_model_options, 5 mbdk_spatial_options)
 *     var VR KIND I J             a variable (value reference VR, modelDescription.xml names
 *                                 it): KIND time; parameters mass I, inertia I, freal I J
 *                                 (force-table row I, slot J, 0-based), step; inputs input I J
 *                                 (a load's slot: mbdk_stepper_set_force); outputs y I (state),
 *                                 lambda I, reaction I J (planar joint I, component J),
 *                                 out I (mbdk_stepper_outputs' I; 5 is their energy sum)
 *
 * Parameters are fixed: set before fmi3ExitInitializationMode, which builds the stepper
 * (mbdk_stepper_create_scene, _index3, _spatial, _spatial_index3 with simulate's options, so
 * that the FMU's states are simulate's bits). fmi3DoStep advances the stepper over the
 * communication step with its own steps of h (a communication point within 1e-9 h of the grid
 * t0 + k h is taken on the grid). Inputs act from the communication point they are set at.
 * fmi3GetFMUState / fmi3SetFMUState copy the whole stepper (mbdk_stepper_copy), so a rolled-back
 * step repeats bit for bit. A kernel failure is fmi3Error with the status's name and message
 * (and the watch's report on a drift) through the logger; the instance keeps its last good
 * state readable and refuses further steps. Nothing is printed; only memory short of a state
 * copy (mbdk_stepper_copy, an intrinsic Fortran assignment) would end the process.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "mbdk.h"

enum var_kind { V_TIME, V_MASS, V_INERTIA, V_FREAL, V_STEP, V_INPUT, V_Y, V_LAMBDA,
                V_REACTION, V_OUT };
static const char *const VAR_KINDS[] = {"time", "mass", "inertia", "freal", "step", "input",
                                        "y", "lambda", "reaction", "out"};
enum { NKINDS = sizeof VAR_KINDS / sizeof VAR_KINDS[0], OUT_ENERGY = MBDK_STEPPER_NOUT };

typedef struct {
    unsigned vr;
    int kind, i, j;
    double value;               /* parameters and inputs: the value set */
} variable;

enum phase { INSTANTIATED, INITIALIZATION, STEP, TERMINATED, FAILED };

typedef struct {
    char name[256], resources[4096];
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    int logging;
    int phase;
    mbdk_scene_tables sc;
    int index3;
    mbdk_options ode;
    mbdk_index3_options i3;
    mbdk_model_options model;
    mbdk_spatial_options spatial;
    variable *vars;
    int nvars;
    mbdk_stepper *s;
    int n, m;
    double t;
    double *y, *lam, *reac, out[MBDK_STEPPER_NOUT];
    int have_y, have_lam, have_reac, have_out;
} instance;

/* a saved state: the stepper and the inputs' values */
typedef struct {
    mbdk_stepper *s;
    double t;
    double *inputs;
    int phase;
} saved_state;

static void logf_(instance *in, fmi3Status status, const char *category, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    if (!in || !in->log) return;
    if (status == fmi3OK && !in->logging) return;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    in->log(in->env, status, category, msg);
}

/* the kernel's status as the logger's text: its name and message */
static fmi3Status kernel_error(instance *in, int status, const char *what)
{
    char name[64] = "", msg[512] = "";
    int i, code;
    for (i = 1; mbdk_status_entry(i, &code, name, sizeof name) == MBDK_SUCCESS; i++)
        if (code == status) break;
    mbdk_status_message(status, msg, sizeof msg);
    logf_(in, fmi3Error, "logStatusError", "%s: %s: MBDK_%s: %s", in->name, what, name, msg);
    return fmi3Error;
}

/* ---- reading the resources ------------------------------------------------------------------ */

static int set_field(instance *in, int id, const char *field, const char *text)
{
    char name[64];
    int nbytes, nfields, k, offset, type;
    char *base;
    switch (id) {
    case 2: base = (char *)&in->ode; break;
    case 3: base = (char *)&in->i3; break;
    case 4: base = (char *)&in->model; break;
    case 5: base = (char *)&in->spatial; break;
    default: return 0;
    }
    if (mbdk_struct_info(id, name, sizeof name, &nbytes, &nfields) != MBDK_SUCCESS) return 0;
    for (k = 1; k <= nfields; k++) {
        if (mbdk_struct_field(id, k, name, sizeof name, &offset, &type) != MBDK_SUCCESS) return 0;
        if (strcmp(name, field) != 0) continue;
        switch (type) {
        case 1: *(int *)(base + offset) = (int)strtol(text, NULL, 10); return 1;
        case 2: *(long long *)(base + offset) = strtoll(text, NULL, 10); return 1;
        case 3: *(double *)(base + offset) = strtod(text, NULL); return 1;
        default: return 1;      /* pointers (the interrupt flag) stay NULL */
        }
    }
    return 0;
}

static int read_run(instance *in, const char *path)
{
    char line[512], word[64], a[128], b[128];
    int id, lineno = 0, cap = 0, vr, i, j, k;
    FILE *f = fopen(path, "r");
    if (!f) {
        logf_(in, fmi3Error, "logStatusError", "%s: cannot open %s", in->name, path);
        return 0;
    }
    mbdk_default_options(&in->ode);
    mbdk_index3_default_options(&in->i3);
    mbdk_model_default_options(&in->model);
    mbdk_spatial_default_options(&in->spatial);
    while (fgets(line, sizeof line, f)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n') continue;
        if (sscanf(line, "%63s", word) != 1) continue;
        if (strcmp(word, "mbdk-fmu") == 0) continue;
        if (strcmp(word, "index3") == 0 && sscanf(line, "%*s %d", &in->index3) == 1) continue;
        if (strcmp(word, "opt") == 0 && sscanf(line, "%*s %d %127s %127s", &id, a, b) == 3 &&
            set_field(in, id, a, b))
            continue;
        if (strcmp(word, "var") == 0 && sscanf(line, "%*s %d %127s %d %d", &vr, a, &i, &j) == 4) {
            for (k = 0; k < NKINDS && strcmp(a, VAR_KINDS[k]) != 0; k++) {}
            if (k < NKINDS && vr >= 0) {
                if (in->nvars == cap) {
                    variable *v;
                    cap = cap ? 2 * cap : 64;
                    v = realloc(in->vars, sizeof *v * (size_t)cap);
                    if (!v) break;
                    in->vars = v;
                }
                in->vars[in->nvars++] = (variable){(unsigned)vr, k, i, j, 0.0};
                continue;
            }
        }
        logf_(in, fmi3Error, "logStatusError", "%s: %s line %d: not understood: %s", in->name,
              path, lineno, line);
        fclose(f);
        return 0;
    }
    fclose(f);
    return 1;
}

static variable *find(instance *in, unsigned vr)
{
    int k;
    for (k = 0; k < in->nvars; k++)
        if (in->vars[k].vr == vr) return &in->vars[k];
    return NULL;
}

static int freal_width(const instance *in)
{
    return in->sc.kind == MBDK_SCENE_SPATIAL ? MBDK_SPATIAL_FORCE_REALS : 12;
}

/* where a parameter or input lives in the tables (NULL: out of the tables' range) */
static double *table_slot(instance *in, const variable *v)
{
    int w = freal_width(in);
    switch (v->kind) {
    case V_MASS: return v->i >= 0 && v->i < in->sc.nb ? &in->sc.mass[v->i] : NULL;
    case V_INERTIA:
        return in->sc.kind == MBDK_SCENE_PLANAR && v->i >= 0 && v->i < in->sc.nb
                   ? &in->sc.inertia[v->i] : NULL;
    case V_FREAL:
    case V_INPUT:
        return v->i >= 0 && v->i < in->sc.nf && v->j >= 0 && v->j < w
                   ? &in->sc.freal[(size_t)v->i * (size_t)w + (size_t)v->j] : NULL;
    case V_STEP: return in->index3 ? &in->i3.h : &in->ode.h;
    default: return NULL;
    }
}

static void free_arrays(instance *in)
{
    mbdk_stepper_destroy(in->s);
    in->s = NULL;
    free(in->y);
    free(in->lam);
    free(in->reac);
    in->y = in->lam = in->reac = NULL;
    mbdk_scene_tables_free(&in->sc);
}

/* the tables and the variables' start values (instantiation and reset) */
static int load(instance *in)
{
    char path[4200], msg[512];
    int k, status;
    snprintf(path, sizeof path, "%sscene.tables.toml", in->resources);
    status = mbdk_scene_tables_read(path, &in->sc, msg, sizeof msg);
    if (status != MBDK_SUCCESS) {
        logf_(in, fmi3Error, "logStatusError", "%s: %s", in->name, msg);
        return 0;
    }
    for (k = 0; k < in->nvars; k++) {
        double *p = table_slot(in, &in->vars[k]);
        int kind = in->vars[k].kind;
        if ((kind >= V_MASS && kind <= V_INPUT) && !p) {
            logf_(in, fmi3Error, "logStatusError",
                  "%s: variable %u (%s %d %d) is outside the scene's tables", in->name,
                  in->vars[k].vr, VAR_KINDS[kind], in->vars[k].i, in->vars[k].j);
            return 0;
        }
        if (p) in->vars[k].value = *p;
    }
    in->t = in->sc.t0;
    in->phase = INSTANTIATED;
    in->have_y = in->have_lam = in->have_reac = in->have_out = 0;
    return 1;
}

/* ---- instantiation ------------------------------------------------------------------------- */

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible,
                                         fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    instance *in;
    char path[4200];
    size_t len;
    (void)instantiationToken; (void)visible; (void)eventModeUsed; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    in = calloc(1, sizeof *in);
    if (!in) return NULL;
    snprintf(in->name, sizeof in->name, "%s", instanceName ? instanceName : "mbdk");
    in->env = instanceEnvironment;
    in->log = logMessage;
    in->logging = loggingOn;
    if (!resourcePath) {
        logf_(in, fmi3Error, "logStatusError", "%s: no resource path", in->name);
        free(in);
        return NULL;
    }
    snprintf(in->resources, sizeof in->resources, "%s", resourcePath);
    len = strlen(in->resources);
    if (len > 0 && in->resources[len - 1] != '/' && len + 1 < sizeof in->resources)
        strcat(in->resources, "/");
    snprintf(path, sizeof path, "%sfmu.txt", in->resources);
    if (!read_run(in, path) || !load(in)) {
        free_arrays(in);
        free(in->vars);
        free(in);
        return NULL;
    }
    return in;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "mbdk FMUs are co-simulation FMUs: model exchange is not provided");
    (void)instanceName;
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "mbdk FMUs are co-simulation FMUs: scheduled execution is not provided");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance_)
{
    instance *in = instance_;
    if (!in) return;
    free_arrays(in);
    free(in->vars);
    free(in);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance_, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    instance *in = instance_;
    (void)nCategories; (void)categories;
    if (!in) return fmi3Error;
    in->logging = loggingOn;
    return fmi3OK;
}

/* ---- initialisation: the stepper ----------------------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance_, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    instance *in = instance_;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!in || in->phase != INSTANTIATED) return fmi3Error;
    if (startTime != in->sc.t0) {
        logf_(in, fmi3Error, "logStatusError",
              "%s: the scene's state is at t = %.17g, not at the start time %.17g asked for "
              "(export the FMU with that t0)", in->name, in->sc.t0, startTime);
        return fmi3Error;
    }
    in->phase = INITIALIZATION;
    return fmi3OK;
}

static int create_stepper(instance *in)
{
    mbdk_scene_tables *sc = &in->sc;
    if (sc->kind == MBDK_SCENE_PLANAR && in->index3)
        return mbdk_stepper_create_index3(sc->nb, sc->mass, sc->inertia, sc->nj, sc->jint,
                                          sc->jreal, sc->nf, sc->fint, sc->freal, &in->i3,
                                          sc->t0, sc->y0, &in->s);
    if (sc->kind == MBDK_SCENE_PLANAR)
        return mbdk_stepper_create_scene(sc->nb, sc->mass, sc->inertia, sc->nj, sc->jint,
                                         sc->jreal, sc->nf, sc->fint, sc->freal, &in->model,
                                         &in->ode, sc->t0, sc->y0, &in->s);
    if (in->index3)
        return mbdk_stepper_create_spatial_index3(sc->nb, sc->mass, sc->inertia, sc->nj,
                                                  sc->jtype, sc->jbody, sc->jreal, sc->nf,
                                                  sc->ftype, sc->fbody, sc->freal, &in->spatial,
                                                  &in->i3, sc->t0, sc->y0, &in->s);
    return mbdk_stepper_create_spatial(sc->nb, sc->mass, sc->inertia, sc->nj, sc->jtype,
                                       sc->jbody, sc->jreal, sc->nf, sc->ftype, sc->fbody,
                                       sc->freal, &in->spatial, &in->ode, sc->t0, sc->y0, &in->s);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance_)
{
    instance *in = instance_;
    int status, k;
    if (!in || in->phase != INITIALIZATION) return fmi3Error;
    for (k = 0; k < in->nvars; k++) {
        double *p = table_slot(in, &in->vars[k]);
        if (p) *p = in->vars[k].value;
    }
    status = create_stepper(in);
    if (status == MBDK_SUCCESS) status = mbdk_stepper_size(in->s, &in->n, &in->m);
    if (status != MBDK_SUCCESS) {
        in->phase = FAILED;
        return kernel_error(in, status, "the stepper could not be created");
    }
    in->y = calloc((size_t)in->n + 1, sizeof(double));
    in->lam = calloc((size_t)in->m + 1, sizeof(double));
    in->reac = calloc(3 * (size_t)in->sc.nj + 1, sizeof(double));
    if (!in->y || !in->lam || !in->reac) {
        in->phase = FAILED;
        mbdk_stepper_destroy(in->s);
        in->s = NULL;
        return kernel_error(in, MBDK_ERR_NO_MEMORY, "the outputs' arrays");
    }
    in->phase = STEP;
    in->have_y = in->have_lam = in->have_reac = in->have_out = 0;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance_)
{
    return instance_ ? fmi3OK : fmi3Error;
}

fmi3Status fmi3Terminate(fmi3Instance instance_)
{
    instance *in = instance_;
    if (!in) return fmi3Error;
    if (in->phase != FAILED) in->phase = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance_)
{
    instance *in = instance_;
    char path[4200];
    if (!in) return fmi3Error;
    free_arrays(in);
    /* the options and variables as exported (a parameter such as the step was written into
     * the options when initialisation ended) */
    free(in->vars);
    in->vars = NULL;
    in->nvars = 0;
    in->phase = FAILED;
    snprintf(path, sizeof path, "%sfmu.txt", in->resources);
    return read_run(in, path) && load(in) ? fmi3OK : fmi3Error;
}

/* ---- stepping ------------------------------------------------------------------------------ */

fmi3Status fmi3DoStep(fmi3Instance instance_, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    instance *in = instance_;
    double h, t0, target, k, t_now;
    int status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (!in) return fmi3Error;
    if (lastSuccessfulTime) *lastSuccessfulTime = in->t;
    if (in->phase == FAILED) {
        logf_(in, fmi3Error, "logStatusError",
              "%s: a step failed at t = %.17g: roll back (fmi3SetFMUState) or reset", in->name,
              in->t);
        return fmi3Error;
    }
    if (in->phase != STEP || !in->s) return fmi3Error;
    h = in->index3 ? in->i3.h : in->ode.h;
    if (!(communicationStepSize >= 0.0) ||
        fabs(currentCommunicationPoint - in->t) > 1e-9 * h + 1e-12 * fabs(in->t)) {
        logf_(in, fmi3Error, "logStatusError",
              "%s: doStep from t = %.17g with step %.17g, but the FMU is at t = %.17g", in->name,
              currentCommunicationPoint, communicationStepSize, in->t);
        return fmi3Error;
    }
    /* a communication point within 1e-9 h of the grid t0 + k h is the grid point: a master
     * that adds its steps up lands there, and the states stay simulate's */
    t0 = in->sc.t0;
    target = currentCommunicationPoint + communicationStepSize;
    k = nearbyint((target - t0) / h);
    if (fabs(t0 + k * h - target) <= 1e-9 * h) target = t0 + k * h;
    status = mbdk_stepper_advance(in->s, target);
    in->have_y = in->have_lam = in->have_reac = in->have_out = 0;
    mbdk_stepper_state(in->s, &t_now, in->y, in->n);
    in->t = t_now;
    if (lastSuccessfulTime) *lastSuccessfulTime = t_now;
    if (status != MBDK_SUCCESS) {
        mbdk_watch_report rep;
        in->phase = FAILED;
        kernel_error(in, status, "step failed");
        if (mbdk_stepper_watch_report(in->s, &rep) == MBDK_SUCCESS && rep.quantity > 0) {
            static const char *const what[] = {"", "position", "velocity", "energy",
                                               "momentum", "quaternion norm"};
            logf_(in, fmi3Error, "logStatusError",
                  "%s: the watch: %s (row %d) %.3g of its scale %.3g at t = %.17g, against the "
                  "tolerance %.3g; last good at t = %.17g", in->name,
                  what[rep.quantity < 6 ? rep.quantity : 0], rep.row, rep.value, rep.scale, rep.t,
                  rep.tol, rep.t_good);
        }
        logf_(in, fmi3Error, "logStatusError",
              "%s: the last good state, at t = %.17g, stays readable", in->name, t_now);
        return fmi3Error;
    }
    return fmi3OK;
}

/* ---- values -------------------------------------------------------------------------------- */

static fmi3Status value_of(instance *in, variable *v, double *x)
{
    int status = MBDK_SUCCESS;
    if (v->kind == V_TIME) {
        *x = in->t;
        return fmi3OK;
    }
    if (v->kind >= V_MASS && v->kind <= V_INPUT) {
        *x = v->value;
        return fmi3OK;
    }
    if (!in->s) {
        /* before the stepper: the initial state, no derived outputs yet */
        if (v->kind == V_Y && v->i >= 0 && v->i < in->sc.n) {
            *x = in->sc.y0[v->i];
            return fmi3OK;
        }
        *x = 0.0;
        return fmi3OK;
    }
    switch (v->kind) {
    case V_Y:
        if (!in->have_y) {
            double t;
            status = mbdk_stepper_state(in->s, &t, in->y, in->n);
            in->have_y = status == MBDK_SUCCESS;
        }
        if (v->i < 0 || v->i >= in->n) return fmi3Error;
        *x = in->y[v->i];
        break;
    case V_LAMBDA:
        if (!in->have_lam) {
            status = mbdk_stepper_multipliers(in->s, in->lam, in->m);
            in->have_lam = status == MBDK_SUCCESS;
        }
        if (v->i < 0 || v->i >= in->m) return fmi3Error;
        *x = in->lam[v->i];
        break;
    case V_REACTION:
        if (!in->have_reac) {
            status = mbdk_stepper_reactions(in->s, in->reac, in->sc.nj);
            in->have_reac = status == MBDK_SUCCESS;
        }
        if (v->i < 0 || v->i >= in->sc.nj || v->j < 0 || v->j > 2) return fmi3Error;
        *x = in->reac[3 * v->i + v->j];
        break;
    case V_OUT:
        if (!in->have_out) {
            status = mbdk_stepper_outputs(in->s, in->out, MBDK_STEPPER_NOUT);
            in->have_out = status == MBDK_SUCCESS;
        }
        if (v->i == OUT_ENERGY) *x = in->out[0] + in->out[1] + in->out[2];
        else if (v->i >= 0 && v->i < MBDK_STEPPER_NOUT) *x = in->out[v->i];
        else return fmi3Error;
        break;
    default: return fmi3Error;
    }
    if (status != MBDK_SUCCESS) return kernel_error(in, status, "an output could not be evaluated");
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    instance *in = instance_;
    size_t k;
    if (!in || nValues < nValueReferences) return fmi3Error;
    for (k = 0; k < nValueReferences; k++) {
        variable *v = find(in, valueReferences[k]);
        if (!v) {
            logf_(in, fmi3Error, "logStatusError", "%s: no Float64 variable %u", in->name,
                  valueReferences[k]);
            return fmi3Error;
        }
        if (value_of(in, v, &values[k]) != fmi3OK) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    instance *in = instance_;
    size_t k;
    if (!in || nValues < nValueReferences) return fmi3Error;
    for (k = 0; k < nValueReferences; k++) {
        variable *v = find(in, valueReferences[k]);
        int parameter;
        if (!v) {
            logf_(in, fmi3Error, "logStatusError", "%s: no Float64 variable %u", in->name,
                  valueReferences[k]);
            return fmi3Error;
        }
        parameter = v->kind >= V_MASS && v->kind <= V_STEP;
        if (!(parameter || v->kind == V_INPUT)) {
            logf_(in, fmi3Error, "logStatusError",
                  "%s: variable %u is an output (or the time) and cannot be set", in->name,
                  v->vr);
            return fmi3Error;
        }
        if (!isfinite(values[k])) {
            logf_(in, fmi3Error, "logStatusError", "%s: variable %u set to %g: not finite",
                  in->name, v->vr, values[k]);
            return fmi3Error;
        }
        if (parameter && in->phase != INSTANTIATED && in->phase != INITIALIZATION) {
            logf_(in, fmi3Error, "logStatusError",
                  "%s: variable %u is a fixed parameter: set it before initialisation ends",
                  in->name, v->vr);
            return fmi3Error;
        }
        if (v->kind == V_INPUT && in->s) {
            int status = mbdk_stepper_set_force(in->s, v->i + 1, v->j + 1, values[k]);
            if (status != MBDK_SUCCESS) return kernel_error(in, status, "an input was refused");
            in->have_lam = in->have_reac = 0;
        }
        v->value = values[k];
    }
    return fmi3OK;
}

/* ---- FMU state: the whole stepper ---------------------------------------------------------- */

static int count_inputs(const instance *in)
{
    int k, n = 0;
    for (k = 0; k < in->nvars; k++) n += in->vars[k].kind == V_INPUT;
    return n;
}

fmi3Status fmi3GetFMUState(fmi3Instance instance_, fmi3FMUState *FMUState)
{
    instance *in = instance_;
    saved_state *st;
    int k, i = 0, status;
    if (!in || !FMUState) return fmi3Error;
    if (!in->s) {
        logf_(in, fmi3Error, "logStatusError",
              "%s: the state can be saved once initialisation has ended", in->name);
        return fmi3Error;
    }
    st = *FMUState;
    if (!st) {
        st = calloc(1, sizeof *st);
        if (!st) return kernel_error(in, MBDK_ERR_NO_MEMORY, "saving the state");
        st->inputs = calloc((size_t)count_inputs(in) + 1, sizeof(double));
        if (!st->inputs) {
            free(st);
            return kernel_error(in, MBDK_ERR_NO_MEMORY, "saving the state");
        }
    }
    status = mbdk_stepper_copy(in->s, &st->s);
    if (status != MBDK_SUCCESS) {
        if (!*FMUState) {
            free(st->inputs);
            free(st);
        }
        return kernel_error(in, status, "saving the state");
    }
    for (k = 0; k < in->nvars; k++)
        if (in->vars[k].kind == V_INPUT) st->inputs[i++] = in->vars[k].value;
    st->t = in->t;
    st->phase = in->phase;
    *FMUState = st;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance_, fmi3FMUState FMUState)
{
    instance *in = instance_;
    saved_state *st = FMUState;
    int k, i = 0, status;
    if (!in || !st || !in->s) return fmi3Error;
    status = mbdk_stepper_copy(st->s, &in->s);
    if (status != MBDK_SUCCESS) return kernel_error(in, status, "restoring a state");
    for (k = 0; k < in->nvars; k++)
        if (in->vars[k].kind == V_INPUT) in->vars[k].value = st->inputs[i++];
    in->t = st->t;
    in->phase = st->phase;
    in->have_y = in->have_lam = in->have_reac = in->have_out = 0;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance_, fmi3FMUState *FMUState)
{
    saved_state *st;
    (void)instance_;
    if (!FMUState || !*FMUState) return fmi3OK;
    st = *FMUState;
    mbdk_stepper_destroy(st->s);
    free(st->inputs);
    free(st);
    *FMUState = NULL;
    return fmi3OK;
}

/* ---- what an mbdk FMU does not provide: an error that says so ------------------------------- */

static fmi3Status unsupported(fmi3Instance instance_, const char *what)
{
    instance *in = instance_;
    if (in) logf_(in, fmi3Error, "logStatusError", "%s: %s is not provided by mbdk FMUs",
                  in->name, what);
    return fmi3Error;
}

#define NO_VALUES(NAME, TYPE, CONST)                                                             \
    fmi3Status NAME(fmi3Instance instance_, const fmi3ValueReference valueReferences[],         \
                    size_t nValueReferences, CONST TYPE values[], size_t nValues)               \
    {                                                                                            \
        (void)valueReferences; (void)values; (void)nValues;                                      \
        return nValueReferences == 0 ? fmi3OK : unsupported(instance_, #NAME " (no such variables)"); \
    }
NO_VALUES(fmi3GetFloat32, fmi3Float32, )
NO_VALUES(fmi3GetInt8, fmi3Int8, )
NO_VALUES(fmi3GetUInt8, fmi3UInt8, )
NO_VALUES(fmi3GetInt16, fmi3Int16, )
NO_VALUES(fmi3GetUInt16, fmi3UInt16, )
NO_VALUES(fmi3GetInt32, fmi3Int32, )
NO_VALUES(fmi3GetUInt32, fmi3UInt32, )
NO_VALUES(fmi3GetInt64, fmi3Int64, )
NO_VALUES(fmi3GetUInt64, fmi3UInt64, )
NO_VALUES(fmi3GetBoolean, fmi3Boolean, )
NO_VALUES(fmi3GetString, fmi3String, )
NO_VALUES(fmi3SetFloat32, fmi3Float32, const)
NO_VALUES(fmi3SetInt8, fmi3Int8, const)
NO_VALUES(fmi3SetUInt8, fmi3UInt8, const)
NO_VALUES(fmi3SetInt16, fmi3Int16, const)
NO_VALUES(fmi3SetUInt16, fmi3UInt16, const)
NO_VALUES(fmi3SetInt32, fmi3Int32, const)
NO_VALUES(fmi3SetUInt32, fmi3UInt32, const)
NO_VALUES(fmi3SetInt64, fmi3Int64, const)
NO_VALUES(fmi3SetUInt64, fmi3UInt64, const)
NO_VALUES(fmi3SetBoolean, fmi3Boolean, const)
NO_VALUES(fmi3SetString, fmi3String, const)

fmi3Status fmi3GetBinary(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[],
                         size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return nValueReferences == 0 ? fmi3OK : unsupported(instance_, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues)
{
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    return nValueReferences == 0 ? fmi3OK : unsupported(instance_, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    return nValueReferences == 0 ? fmi3OK : unsupported(instance_, "fmi3GetClock");
}

fmi3Status fmi3SetClock(fmi3Instance instance_, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[])
{
    (void)valueReferences; (void)values;
    return nValueReferences == 0 ? fmi3OK : unsupported(instance_, "fmi3SetClock");
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance_)
{
    return unsupported(instance_, "event mode");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance_,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference; (void)nDependencies;
    return unsupported(instance_, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance_, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies)
{
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)dependencyKinds; (void)nDependencies;
    return unsupported(instance_, "fmi3GetVariableDependencies");
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance_, fmi3FMUState FMUState, size_t *size)
{
    (void)FMUState; (void)size;
    return unsupported(instance_, "serialising an FMU state (canSerializeFMUState is false)");
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance_, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size)
{
    (void)FMUState; (void)serializedState; (void)size;
    return unsupported(instance_, "serialising an FMU state (canSerializeFMUState is false)");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance_, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState)
{
    (void)serializedState; (void)size; (void)FMUState;
    return unsupported(instance_, "serialising an FMU state (canSerializeFMUState is false)");
}

#define DERIVATIVE(NAME)                                                                         \
    fmi3Status NAME(fmi3Instance instance_, const fmi3ValueReference unknowns[], size_t nUnknowns, \
                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], \
                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)                \
    {                                                                                            \
        (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed;   \
        (void)sensitivity; (void)nSensitivity;                                                   \
        return unsupported(instance_, #NAME);                                                    \
    }
DERIVATIVE(fmi3GetDirectionalDerivative)
DERIVATIVE(fmi3GetAdjointDerivative)

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance_)
{
    return unsupported(instance_, "configuration mode");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance_)
{
    return unsupported(instance_, "configuration mode");
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    (void)vr; (void)n; (void)intervals; (void)qualifiers;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    (void)vr; (void)n; (void)counters; (void)resolutions; (void)qualifiers;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                               fmi3Float64 shifts[])
{
    (void)vr; (void)n; (void)shifts;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)vr; (void)n; (void)counters; (void)resolutions;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                  const fmi3Float64 intervals[])
{
    (void)vr; (void)n; (void)intervals;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)vr; (void)n; (void)counters; (void)resolutions;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                               const fmi3Float64 shifts[])
{
    (void)vr; (void)n; (void)shifts;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance_, const fmi3ValueReference vr[], size_t n,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[])
{
    (void)vr; (void)n; (void)counters; (void)resolutions;
    return unsupported(instance_, "clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance_)
{
    return unsupported(instance_, "discrete states");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance_, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    (void)discreteStatesNeedUpdate; (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged; (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined; (void)nextEventTime;
    return unsupported(instance_, "discrete states");
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance_)
{
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance_,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint; (void)enterEventMode; (void)terminateSimulation;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3SetTime(fmi3Instance instance_, fmi3Float64 time)
{
    (void)time;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance_, const fmi3Float64 x[], size_t nx)
{
    (void)x; (void)nx;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance_, fmi3Float64 d[], size_t nx)
{
    (void)d; (void)nx;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance_, fmi3Float64 e[], size_t ne)
{
    (void)e; (void)ne;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance_, fmi3Float64 x[], size_t nx)
{
    (void)x; (void)nx;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance_, fmi3Float64 x[], size_t nx)
{
    (void)x; (void)nx;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance_, size_t *n)
{
    (void)n;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance_, size_t *n)
{
    (void)n;
    return unsupported(instance_, "model exchange");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance_, const fmi3ValueReference vr[],
                                    size_t n, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    (void)vr; (void)n; (void)orders; (void)values; (void)nValues;
    return unsupported(instance_, "output derivatives (maxOutputDerivativeOrder is 0)");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance_, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference; (void)activationTime;
    return unsupported(instance_, "scheduled execution");
}
