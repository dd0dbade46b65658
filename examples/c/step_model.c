// Step an efam.muscle model from C: load the plugin library the way MuJoCo loads any plugin
// library (mj_loadPluginLibrary; the library registers efam.muscle itself when loaded), compile
// the model, hold the muscles at fixed gauge pressures and step.
//
//   step_model PLUGIN_LIBRARY MODEL.xml [PRESSURE_Pa] [STEPS]
//
// PLUGIN_LIBRARY: `efam install-plugin --print-path` prints it (or use a copy in a plugin
// directory: mj_loadAllPluginLibraries loads all of them). The k-th of n efam.muscle actuators
// gets PRESSURE_Pa * (k + 1) / n (unequal: an arm bends). Prints the number of efam.muscle
// actuators, then after the steps the time, qpos and each actuator's force, one per line, with
// 17 significant digits (tests/test_examples_c.py compares them with the same steps in Python).
//
// Build (the mujoco wheel ships libmujoco and the headers; see README.md beside this file):
//   cc -O2 -o step_model step_model.c -I$MJ/include -L$MJ -l:libmujoco.so.3.17.0 -Wl,-rpath,$MJ

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

int main(int argc, char** argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: %s PLUGIN_LIBRARY MODEL.xml [PRESSURE_Pa] [STEPS]\n", argv[0]);
    return 2;
  }
  double pressure_Pa = argc > 3 ? atof(argv[3]) : 200e3;
  int steps = argc > 4 ? atoi(argv[4]) : 500;

  mj_loadPluginLibrary(argv[1]);
  int slot = -1;
  if (!mjp_getPlugin("efam.muscle", &slot)) {
    fprintf(stderr, "%s did not register the efam.muscle plugin\n", argv[1]);
    return 1;
  }

  char error[1000] = "";
  mjModel* m = mj_loadXML(argv[2], NULL, error, sizeof(error));
  if (!m) {
    fprintf(stderr, "cannot load %s: %s\n", argv[2], error);
    if (strstr(error, "efam.muscle")) {
      fprintf(stderr, "hint: load the plugin first: mj_loadPluginLibrary() on the path that "
                      "`efam install-plugin --print-path` prints\n");
    }
    return 1;
  }
  mjData* d = mj_makeData(m);

  int nmuscle = 0;
  for (int i = 0; i < m->nu; i++) {
    nmuscle += m->actuator_plugin[i] >= 0 && m->plugin[m->actuator_plugin[i]] == slot;
  }
  for (int i = 0, k = 0; i < m->nu; i++) {
    if (m->actuator_plugin[i] >= 0 && m->plugin[m->actuator_plugin[i]] == slot) {
      d->ctrl[i] = pressure_Pa * (k + 1) / nmuscle;  // efam.muscle's control: gauge pressure, Pa
      k++;
    }
  }
  printf("efam.muscle actuators %d\n", nmuscle);

  for (int k = 0; k < steps; k++) {
    mj_step(m, d);
  }
  printf("time %.17g\n", d->time);
  for (int i = 0; i < m->nq; i++) {
    printf("qpos %d %.17g\n", i, d->qpos[i]);
  }
  for (int i = 0; i < m->nu; i++) {
    printf("force %d %.17g\n", i, d->actuator_force[i]);
  }

  mj_deleteData(d);
  mj_deleteModel(m);
  return 0;
}
