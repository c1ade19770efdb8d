// Host shim of the Arduino core API the reference sketch uses, so the unmodified sketch
// compiles with the system g++ and runs on a pseudo-terminal (firmware-in-the-loop tests,
// tactile_sensor/sim/firmware_host.py). Board macros (ARDUINO_ARCH_AVR, ARDUINO_ARCH_RP2040,
// ...) are passed on the command line, as arduino-cli would; like the real cores, only
// non-AVR boards have analogReadResolution().
#pragma once

#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef uint8_t byte;
typedef bool boolean;

// Analog pins are numbered after the 14 digital ones, as on an Uno.
static const uint8_t A0 = 14, A1 = 15, A2 = 16, A3 = 17, A4 = 18, A5 = 19, A6 = 20, A7 = 21;

uint32_t micros();
uint32_t millis();
void delayMicroseconds(unsigned int us);  // sleeps on the host

// Digital pins: a modulated sketch switches its emitters with them; the shim takes any
// output pin driven HIGH as the emitters on (analogRead then gives the "volts" stimulus,
// otherwise the "off" one).
#define LOW 0
#define HIGH 1
#define INPUT 0
#define OUTPUT 1
void pinMode(uint8_t pin, uint8_t mode);
void digitalWrite(uint8_t pin, uint8_t level);

// The code of an ideal converter for the stimulus voltage on `pin` (A0 + channel or the
// channel number): floor(V / Vref * 2^bits), clipped; 10 bits until told otherwise.
int analogRead(uint8_t pin);
#if !defined(ARDUINO_ARCH_AVR)
void analogReadResolution(int bits);
#else
// The AVR ADC control register and its prescaler bits (ADPS2:0 = bits 2..0), as avr/io.h
// names them; it starts as the core's init() leaves it (ADC on, F_CPU / 128), and the
// shim reports the prescaler the sketch chose ("stats").
extern volatile uint8_t host_adcsra;
#define ADCSRA host_adcsra
#define ADPS0 0
#define ADPS1 1
#define ADPS2 2
#endif

// A UART with a small transmit buffer (the Uno's 64 bytes) draining into the
// pseudo-terminal: write() blocks while the buffer is full, as HardwareSerial does.
class HostSerial {
 public:
  void begin(unsigned long baud);
  int availableForWrite();
  size_t write(const uint8_t *data, size_t size);
  size_t write(uint8_t byte);
  explicit operator bool() const { return true; }
};

extern HostSerial Serial;

void setup();
void loop();
