/* Python module shell around the firmware core + sim board; the API itself is loaded with ctypes. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef fw_module = {
    PyModuleDef_HEAD_INIT, "_fw",
    "Firmware core and sim board (C API loaded by pmsm_hil.emulator.fwlib).", -1, NULL,
    NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__fw(void) { return PyModule_Create(&fw_module); }
