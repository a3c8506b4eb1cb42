# Third-party dependencies, all from Debian 12 (packaging/install-deps.sh).
find_package(PkgConfig REQUIRED)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs features2d calib3d video)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(GDAL REQUIRED)
find_package(SQLite3 REQUIRED)
find_package(Ceres REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
pkg_check_modules(LIBAV REQUIRED IMPORTED_TARGET libavformat libavcodec libswscale libavutil)

# GeographicLib ships no CMake package on Debian; wrap pkg-config in our own target.
pkg_check_modules(GEOGRAPHICLIB REQUIRED IMPORTED_TARGET geographiclib)
add_library(saker::geographiclib ALIAS PkgConfig::GEOGRAPHICLIB)

if(SAKER_BUILD_GUI)
  find_package(Qt6 REQUIRED COMPONENTS Widgets Test)
endif()
if(SAKER_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
