#pragma once
// The hot loops of detection are compiled twice: for the x86-64 baseline and for
// x86-64-v3 (AVX2, FMA; every x86 server since 2013), and the loader picks one when the
// program starts (GCC function multiversioning through an ifunc). The binary runs on any
// x86-64 and vectorises 8 floats wide where it can. Results are the same to the bit on
// either: the library is built without floating-point contraction (CMakeLists.txt).
#if defined(__x86_64__) && defined(__linux__) && defined(__GNUC__) && !defined(__clang__)
#define DENTMARK_HOT_LOOP [[gnu::target_clones("arch=x86-64-v3", "default")]]
#else
#define DENTMARK_HOT_LOOP
#endif
