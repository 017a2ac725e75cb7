# cmake --install and find_package(lshloc COMPONENTS ...): each layer library is
# a component with its own export file and its own dependencies, so a consumer
# of lshloc::core needs Eigen alone (small_gicp's install/export is the model).
# Components: core (Eigen), io (core; nlohmann-json, zlib, libyaml, libpng),
# figures (core; cairo), eval (core, io), sim (eval). Also installed: the public
# headers, the lshloc tool and the ROS bag converter (lshloc-rosbag-to-carmen).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(LSHLOC_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/lshloc)
foreach(component core io figures eval sim)
  install(TARGETS lshloc_${component}
          EXPORT lshloc-${component}-targets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(EXPORT lshloc-${component}-targets NAMESPACE lshloc:: DESTINATION ${LSHLOC_CMAKE_DIR})
endforeach()
install(TARGETS lshloc RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The ROS bag converter beside the tool (standard-library Python: nothing to build).
install(PROGRAMS ${PROJECT_SOURCE_DIR}/scripts/tools/rosbag_to_carmen.py DESTINATION ${CMAKE_INSTALL_BINDIR}
        RENAME lshloc-rosbag-to-carmen)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/lshloc DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lshlocConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/lshlocConfig.cmake
                              INSTALL_DESTINATION ${LSHLOC_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/lshlocConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/lshlocConfig.cmake ${PROJECT_BINARY_DIR}/lshlocConfigVersion.cmake
        DESTINATION ${LSHLOC_CMAKE_DIR})
