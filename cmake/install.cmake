# cmake --install and find_package(lshloc): the five layer libraries as
# lshloc::core, lshloc::io, lshloc::figures, lshloc::eval, lshloc::sim, the
# public headers, the lshloc tool and the ROS bag converter (lshloc-rosbag-to-carmen).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(LSHLOC_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/lshloc)
install(TARGETS lshloc_core lshloc_io lshloc_figures lshloc_eval lshloc_sim
        EXPORT lshlocTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS lshloc RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The ROS bag converter beside the tool (standard-library Python: nothing to build).
install(PROGRAMS ${PROJECT_SOURCE_DIR}/scripts/rosbag_to_carmen.py DESTINATION ${CMAKE_INSTALL_BINDIR}
        RENAME lshloc-rosbag-to-carmen)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/lshloc DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT lshlocTargets NAMESPACE lshloc:: DESTINATION ${LSHLOC_CMAKE_DIR})

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lshlocConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/lshlocConfig.cmake
                              INSTALL_DESTINATION ${LSHLOC_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/lshlocConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/lshlocConfig.cmake ${PROJECT_BINARY_DIR}/lshlocConfigVersion.cmake
        DESTINATION ${LSHLOC_CMAKE_DIR})
