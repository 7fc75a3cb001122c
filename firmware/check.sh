#!/usr/bin/env bash
# Compile-check firmware/continuum_imu for an Arduino UNO with Debian's AVR toolchain
# (packages gcc-avr, avr-libc, arduino-core-avr), in both variants: one MPU9250
# (IMU_COUNT=1, the default) and two on one I2C bus (IMU_COUNT=2). No upload, no
# board needed.
#
#   firmware/check.sh            compile; SKIP (exit 0) if the toolchain is missing
#   FIRMWARE_CHECK_REQUIRED=1 firmware/check.sh   a missing toolchain is a failure
#
# Also checks that flash and RAM fit the ATmega328P (32256 and 2048 bytes).
set -euo pipefail

here="$(cd "$(dirname "$0")" && pwd)"
sketch="$here/continuum_imu/continuum_imu.ino"
core_root="${ARDUINO_AVR_DIR:-/usr/share/arduino/hardware/arduino/avr}"

if ! command -v avr-g++ >/dev/null || [ ! -f "$core_root/cores/arduino/Arduino.h" ]; then
    msg="firmware/check.sh: SKIP: avr-g++ or the Arduino AVR core is missing"
    msg="$msg (apt-get install gcc-avr avr-libc arduino-core-avr)"
    echo "$msg" >&2
    [ "${FIRMWARE_CHECK_REQUIRED:-0}" = "1" ] && exit 1
    exit 0
fi

build="$(mktemp -d)"
trap 'rm -rf "$build"' EXIT
core="$core_root/cores/arduino"
wire="$core_root/libraries/Wire/src"
flags=(-mmcu=atmega328p -DF_CPU=16000000L -DARDUINO=10807 -DARDUINO_AVR_UNO -DARDUINO_ARCH_AVR
       -Os -ffunction-sections -fdata-sections -Wall -Wextra -DDECIMAL_DIG=17
       -I"$core" -I"$core_root/variants/standard" -I"$wire" -I"$wire/utility")
cflags=("${flags[@]}" -std=gnu11)
# DECIMAL_DIG: missing from avr-libc, needed by Debian's WString.cpp
cxxflags=("${flags[@]}" -std=gnu++11 -fno-exceptions -fno-threadsafe-statics -fpermissive)

objs=()
for src in "$core"/*.c "$core"/*.S "$wire"/utility/*.c; do
    obj="$build/$(basename "$src").o"
    avr-gcc "${cflags[@]}" -w -c "$src" -o "$obj"
    objs+=("$obj")
done
for src in "$core"/*.cpp "$wire"/*.cpp; do
    obj="$build/$(basename "$src").o"
    avr-g++ "${cxxflags[@]}" -w -c "$src" -o "$obj"
    objs+=("$obj")
done
# the sketch itself, in each variant: warnings are errors
for imus in 1 2; do
    cp "$sketch" "$build/sketch.cpp"
    avr-g++ "${cxxflags[@]}" -DIMU_COUNT=$imus -Werror -c "$build/sketch.cpp" -o "$build/sketch.o"
    avr-gcc -mmcu=atmega328p -Os -Wl,--gc-sections -o "$build/continuum_imu.elf" \
        "$build/sketch.o" "${objs[@]}" -lm

    read -r text data bss _ < <(avr-size "$build/continuum_imu.elf" | tail -1)
    flash=$((text + data))
    ram=$((data + bss))
    echo "firmware/check.sh: continuum_imu IMU_COUNT=$imus compiles for Arduino UNO: flash $flash/32256 bytes, RAM $ram/2048 bytes"
    [ "$flash" -le 32256 ] || { echo "firmware/check.sh: flash too large" >&2; exit 1; }
    [ "$ram" -le 1536 ] || { echo "firmware/check.sh: static RAM above 1536 bytes leaves too little stack" >&2; exit 1; }
done
