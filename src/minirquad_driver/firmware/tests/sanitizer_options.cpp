// Defaults for AddressSanitizer in every host binary. Leak detection is off: the core has no
// heap to leak, and LeakSanitizer needs ptrace at exit, which some containers refuse (it
// would then fail a clean run). Every other check stays on, and any finding aborts.
extern "C" const char* __asan_default_options() { return "detect_leaks=0"; }
