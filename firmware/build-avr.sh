#!/usr/bin/env bash
# make firmware: cross-compile firmware/tactile_adc for AVR Arduinos with avr-g++ against
# Debian's arduino-core-avr, as the Arduino IDE would (board macros, -Os, gc-sections).
#
# The sketch is compiled with -Wall -Wextra -Werror. It is linked with the core (all of it
# but WString.cpp, which Debian's gcc-avr 5.4 cannot build and the sketch does not use) into
# an .elf and the .hex that avrdude flashes; the size is printed, and a build over the
# board's flash or RAM fails. Boards (FIRMWARE_BOARDS): uno (ATmega328P in DIP, A0-A5),
# nano (ATmega328P in TQFP, A0-A7: the Arduino core's eightanaloginputs variant), mega
# (Mega 2560) and leonardo (ATmega32U4, native USB like the Micro). A board may carry its
# channel count as BOARD:N (TACTILE_CHANNELS, pins A0..A(N-1)); boards without one get
# FIRMWARE_CHANNELS (default 1), and BOARD:N:modulated builds the modulated image
# (TACTILE_MODULATED: emitters switched from pin 2, protocol version 3). Default: "uno mega
# leonardo nano:8 uno:1:modulated nano:8:modulated", the 8-channel Nano being the wrench
# array's image; the sketch refuses more channels than the board has, and a modulated
# build whose channels and emitter pins do not fit the board.
# Output: build/firmware/<board>/ for one channel, build/firmware/<board>-<N>ch/ for N, with
# -modulated after either (FIRMWARE_OUT overrides build/firmware; FIRMWARE_SKETCH another
# sketch).
set -euo pipefail
cd "$(dirname "$0")/.."

AVR=${ARDUINO_AVR_DIR:-/usr/share/arduino/hardware/arduino/avr}
OUT_ROOT=${FIRMWARE_OUT:-build/firmware}
BOARDS=${FIRMWARE_BOARDS:-uno mega leonardo nano:8 uno:1:modulated nano:8:modulated}
CHANNELS=${FIRMWARE_CHANNELS:-1}
SKETCH=${FIRMWARE_SKETCH:-firmware/tactile_adc/tactile_adc.ino}

for tool in avr-gcc avr-g++ avr-size avr-objcopy; do
  if ! command -v "$tool" >/dev/null; then
    echo "make firmware: $tool is missing; install the AVR toolchain with" \
         "'apt-get install gcc-avr avr-libc arduino-core-avr'." >&2
    exit 1
  fi
done
if [[ ! -f $AVR/cores/arduino/Arduino.h ]]; then
  echo "make firmware: the Arduino AVR core is not at $AVR; install it with" \
       "'apt-get install arduino-core-avr' or set ARDUINO_AVR_DIR." >&2
  exit 1
fi

build_board() {  # name channels mode mcu variant board-macro flash-bytes ram-bytes [defines]
  local name=$1 channels=$2 mode=$3 mcu=$4 variant=$5 macro=$6 flash_max=$7 ram_max=$8
  shift 8
  local out=$OUT_ROOT/$name
  ((channels == 1)) || out=$OUT_ROOT/$name-${channels}ch
  local modulated=0
  if [[ $mode == modulated ]]; then
    modulated=1 out=$out-modulated
  fi
  rm -rf "$out"
  mkdir -p "$out/core"
  local common=(-mmcu="$mcu" -Os -ffunction-sections -fdata-sections -DF_CPU=16000000L
                -DARDUINO=10819 -D"$macro" -DARDUINO_ARCH_AVR -DTACTILE_CHANNELS="$channels" -DTACTILE_MODULATED=$modulated "$@"
                -I"$AVR/cores/arduino" -I"$AVR/variants/$variant")
  local cxx=(-std=gnu++11 -fno-exceptions -fno-threadsafe-statics)
  avr-g++ "${common[@]}" "${cxx[@]}" -Wall -Wextra -Werror -x c++ -c "$SKETCH" \
    -o "$out/tactile_adc.o"
  local src obj
  for src in "$AVR"/cores/arduino/*.{c,cpp,S}; do
    [[ $(basename "$src") == WString.cpp ]] && continue
    obj=$out/core/$(basename "$src").o
    case $src in
      *.c) avr-gcc "${common[@]}" -std=gnu11 -w -c "$src" -o "$obj" ;;
      *.cpp) avr-g++ "${common[@]}" "${cxx[@]}" -w -c "$src" -o "$obj" ;;
      *.S) avr-gcc "${common[@]}" -x assembler-with-cpp -c "$src" -o "$obj" ;;
    esac
  done
  avr-gcc -mmcu="$mcu" -Os -Wl,--gc-sections -o "$out/tactile_adc.elf" \
    "$out/tactile_adc.o" "$out"/core/*.o -lm
  avr-objcopy -O ihex -R .eeprom "$out/tactile_adc.elf" "$out/tactile_adc.hex"
  local text data bss
  read -r text data bss _ < <(avr-size "$out/tactile_adc.elf" | tail -1)
  local flash=$((text + data)) ram=$((data + bss))
  local label="$channels channel(s)"
  ((modulated)) && label="$label, modulated"
  echo "firmware $name ($mcu, $label): text $text, data $data, bss $bss bytes; flash $flash of" \
       "$flash_max ($((100 * flash / flash_max)) %), static RAM $ram of $ram_max" \
       "($((100 * ram / ram_max)) %, the rest is stack); $out/tactile_adc.hex"
  if ((flash > flash_max || ram > ram_max)); then
    echo "make firmware: the $name build does not fit the board." >&2
    return 1
  fi
}

for spec in $BOARDS; do
  IFS=: read -r board n mode <<<"$spec"
  n=${n:-$CHANNELS} mode=${mode:-plain}
  if [[ $mode != plain && $mode != modulated ]]; then
    echo "make firmware: '$spec': the third field is 'modulated' or nothing (BOARD:N:modulated)." >&2
    exit 1
  fi
  if ! [[ $n =~ ^[1-8]$ ]]; then
    echo "make firmware: '$n' channels for $board; give 1..8 (BOARD:N or FIRMWARE_CHANNELS)." >&2
    exit 1
  fi
  case $board in
    uno) build_board uno "$n" "$mode" atmega328p standard ARDUINO_AVR_UNO 32256 2048 ;;
    nano) build_board nano "$n" "$mode" atmega328p eightanaloginputs ARDUINO_AVR_NANO 30720 2048 ;;
    mega) build_board mega "$n" "$mode" atmega2560 mega ARDUINO_AVR_MEGA2560 253952 8192 ;;
    leonardo) build_board leonardo "$n" "$mode" atmega32u4 leonardo ARDUINO_AVR_LEONARDO 28672 2560 \
                -DUSB_VID=0x2341 -DUSB_PID=0x8036 '-DUSB_MANUFACTURER="Unknown"' \
                '-DUSB_PRODUCT="Arduino Leonardo"' ;;
    *) echo "make firmware: unknown board '$board'; use uno, nano, mega or leonardo." >&2
       exit 1 ;;
  esac
done
