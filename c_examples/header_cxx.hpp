/*
 * header_cxx.hpp: what the C++ header test's translation units export to each
 * other. Each .cpp includes antumbra.h on its own; linking them into one program
 * proves the header defines nothing (no ODR or multiple-definition clash) and that
 * its extern "C" block gives the functions their C names.
 */
#ifndef ANTUMBRA_HEADER_CXX_HPP
#define ANTUMBRA_HEADER_CXX_HPP

/* Returns the number of failed checks; each prints its own message. */
int header_cxx_a_checks();
int header_cxx_b_checks();

#endif
