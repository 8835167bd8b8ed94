# SPDX-License-Identifier: GPL-3.0-or-later
# Every dependency is a Debian package found through pkg-config (see scripts/install-deps).
find_package(PkgConfig REQUIRED)
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET fftw3f)
pkg_check_modules(GSL REQUIRED IMPORTED_TARGET gsl)
pkg_check_modules(TIFF REQUIRED IMPORTED_TARGET libtiff-4)
pkg_check_modules(PNG REQUIRED IMPORTED_TARGET libpng)
pkg_check_modules(NETCDF REQUIRED IMPORTED_TARGET netcdf)
pkg_check_modules(PLPLOT REQUIRED IMPORTED_TARGET plplot)
pkg_check_modules(STB REQUIRED IMPORTED_TARGET stb)
pkg_check_modules(JPEG REQUIRED IMPORTED_TARGET libjpeg)
find_package(OpenMP REQUIRED COMPONENTS C)
find_library(FFTW3F_OMP fftw3f_omp)
find_library(MATH_LIB m)

find_package(MPI COMPONENTS C QUIET)
if(MPI_C_FOUND)
  option(RPIV_MPI "Build MPI scale-out into rpiv piv and rpiv synth" ON)
else()
  option(RPIV_MPI "Build MPI scale-out into rpiv piv and rpiv synth" OFF)
endif()

add_library(rpiv_deps INTERFACE)
target_link_libraries(rpiv_deps INTERFACE PkgConfig::FFTW3F PkgConfig::GSL PkgConfig::TIFF
  PkgConfig::PNG PkgConfig::NETCDF PkgConfig::PLPLOT PkgConfig::STB PkgConfig::JPEG
  OpenMP::OpenMP_C ${MATH_LIB})
if(RPIV_MPI)
  target_link_libraries(rpiv_deps INTERFACE MPI::MPI_C)
  target_compile_definitions(rpiv_deps INTERFACE RPIV_HAVE_MPI=1)
endif()
