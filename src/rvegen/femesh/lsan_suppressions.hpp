// For the executables that mesh with Gmsh, in sanitizer builds: Gmsh and OpenCASCADE leave
// memory they allocated for themselves unfreed at exit, and LeakSanitizer would report it; leaks
// with their frames in the stack are theirs. Include this in exactly one source file of each such
// executable (it defines LeakSanitizer's hook, which only the executable itself can define).
#pragma once

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libgmsh.so\nleak:libTK\n";
}
#endif
#endif
