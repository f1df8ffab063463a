# SPDX-License-Identifier: Apache-2.0
# Runs at install time (deploy/CMakeLists.txt sets the FOVEA_* variables before it): writes the
# systemd unit with the installed binary's and configuration's paths, and installs the example
# configuration unless one is already there.

# GNUInstallDirs' rule for the configuration directory: absolute as given, /etc for the prefix /usr,
# else under the prefix.
function(fovea_install_path out dir)
  if(IS_ABSOLUTE "${dir}")
    set(${out} "${dir}" PARENT_SCOPE)
  elseif(dir STREQUAL "etc" AND CMAKE_INSTALL_PREFIX STREQUAL "/usr")
    set(${out} "/etc" PARENT_SCOPE)
  else()
    set(${out} "${CMAKE_INSTALL_PREFIX}/${dir}" PARENT_SCOPE)
  endif()
endfunction()

fovea_install_path(bindir "${FOVEA_BINDIR}")
fovea_install_path(confdir "${FOVEA_SYSCONFDIR}")
fovea_install_path(unitdir "${FOVEA_SYSTEMD_UNIT_DIR}")
set(config "${confdir}/fovea/trackerd.toml")

file(READ "${FOVEA_DEPLOY_DIR}/fovea-trackerd.service" unit)
foreach(path /usr/local/bin/fovea-trackerd /etc/fovea/trackerd.toml)
  string(FIND "${unit}" "${path}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "deploy/fovea-trackerd.service no longer names ${path}: update deploy/install-files.cmake")
  endif()
endforeach()
string(REPLACE "/usr/local/bin/fovea-trackerd" "${bindir}/fovea-trackerd" unit "${unit}")
string(REPLACE "/etc/fovea/trackerd.toml" "${config}" unit "${unit}")
file(WRITE "${FOVEA_STAGE_DIR}/fovea-trackerd.service" "${unit}")
file(INSTALL DESTINATION "${unitdir}" TYPE FILE PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ
     FILES "${FOVEA_STAGE_DIR}/fovea-trackerd.service")

if(EXISTS "$ENV{DESTDIR}${config}")
  message(STATUS "Keeping: $ENV{DESTDIR}${config} (the example is ${FOVEA_DEPLOY_DIR}/trackerd.toml)")
else()
  file(INSTALL DESTINATION "${confdir}/fovea" TYPE FILE PERMISSIONS OWNER_READ OWNER_WRITE GROUP_READ WORLD_READ
       FILES "${FOVEA_DEPLOY_DIR}/trackerd.toml")
endif()
