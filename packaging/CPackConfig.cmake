# CPack: `cpack -G DEB` in a build directory makes saker_<version>_amd64.deb.
set(CPACK_PACKAGE_NAME "saker")
set(CPACK_PACKAGE_VENDOR "Saker")
set(CPACK_PACKAGE_CONTACT "Saker developers <saker@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "Analyst workstation for airborne video with STANAG 4609 metadata")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_GENERATOR "DEB")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION "science")
# Runtime libraries are found by dpkg-shlibdeps from the installed binaries.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_STRIP_FILES ON)

install(FILES ${PROJECT_SOURCE_DIR}/packaging/saker.desktop DESTINATION share/applications)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/saker-mission.xml DESTINATION share/mime/packages)
install(FILES ${PROJECT_SOURCE_DIR}/resources/icons/saker.svg
        DESTINATION share/icons/hicolor/scalable/apps)
include(CPack)
