/*
 * header_cxx_main.cpp: runs the checks of both C++ translation units. Includes
 * the header a third time, in the TU that holds main.
 */
#include "antumbra.h"
#include "header_cxx.hpp"

#include <cstdio>

int main()
{
    const int failures = header_cxx_a_checks() + header_cxx_b_checks();
    if (failures != 0) {
        std::fprintf(stderr, "header_cxx: %d check(s) failed\n", failures);
        return 1;
    }
    std::printf("header_cxx: antumbra %s from three C++11 translation units: ok\n", antumbra_version_string());
    return 0;
}
