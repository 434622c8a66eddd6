# Makes a package that generates Python interfaces build against the ROS 2 wheels from PyPI.
#
# Use: colcon build --cmake-args -DCMAKE_PROJECT_INCLUDE=<this file>
#        -DPython3_EXECUTABLE=<python> -DPython3_INCLUDE_DIR=<include dir>
#        -DPython3_NumPy_INCLUDE_DIR=<numpy include dir>
#
# The wheels' exported targets <pkg>::<pkg>__rosidl_generator_py name, as include directories,
# the Python and NumPy headers of the machine the wheels were built on
# (/opt/python/cp3XY-cp3XY/...). CMake refuses an imported target whose include directory does
# not exist, so at the end of the project's top directory these are replaced with the
# directories given here, the ones FindPython3 uses for the package's own Python extension.
include_guard(GLOBAL)
if(CMAKE_VERSION VERSION_LESS 3.21)
  message(FATAL_ERROR "wheel_python_includes.cmake needs CMake 3.21 or newer")
endif()
foreach(_required Python3_INCLUDE_DIR Python3_NumPy_INCLUDE_DIR)
  if(NOT IS_DIRECTORY "${${_required}}")
    message(FATAL_ERROR "wheel_python_includes.cmake: -D${_required}=<dir> names no directory")
  endif()
endforeach()

function(_repoint_wheel_python_includes)
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs "${_target}" INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs MATCHES "(^|;)/opt/python/")
      continue()
    endif()
    list(TRANSFORM _dirs REPLACE "^/opt/python/[^;]*/numpy/_core/include$"
      "${Python3_NumPy_INCLUDE_DIR}")
    list(TRANSFORM _dirs REPLACE "^/opt/python/[^;]*/include/python3[.0-9]*$"
      "${Python3_INCLUDE_DIR}")
    set_target_properties("${_target}" PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_dirs}")
  endforeach()
endfunction()
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _repoint_wheel_python_includes)
