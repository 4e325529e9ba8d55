# Included by the interface packages of interfaces/ after rosidl_generate_interfaces().
#
# The message packages from PyPI export their <pkg>__rosidl_generator_py targets with the Python
# and NumPy include directories of the machine the wheels were built on, which do not exist here
# (CMake refuses a target that uses them). Point every such imported target at this machine's
# Python and NumPy headers instead; rosidl_generator_py has run find_package(Python3 ... NumPy)
# above. Only these in-memory target properties change, never the installed files.
get_property(_imported DIRECTORY PROPERTY IMPORTED_TARGETS)
foreach(_target IN LISTS _imported)
  if(_target MATCHES "__rosidl_generator_py$")
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    set(_existing "")
    foreach(_dir IN LISTS _dirs)
      if(_dir AND EXISTS "${_dir}")
        list(APPEND _existing "${_dir}")
      endif()
    endforeach()
    list(APPEND _existing ${Python3_INCLUDE_DIRS} ${Python3_NumPy_INCLUDE_DIRS})
    list(REMOVE_DUPLICATES _existing)
    set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_existing}")
  endif()
endforeach()
