# CMake toolchain file: bare-metal Cortex-M4F (STM32F4) with the GNU Arm Embedded toolchain
# (Debian gcc-arm-none-eabi + libstdc++-arm-none-eabi-newlib).
#   cmake -S cpp/firmware -B build/firmware -DCMAKE_TOOLCHAIN_FILE=cpp/firmware/cmake/arm-none-eabi.cmake \
#         -DGYRODRIFT_CONFIG=my_imu.toml
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy CACHE FILEPATH "objcopy")
set(CMAKE_SIZE arm-none-eabi-size CACHE FILEPATH "size")
# The compiler check links a test program: without start files and a linker script that
# would fail on bare metal, so check a static library instead.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
