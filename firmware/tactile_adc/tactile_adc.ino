// Reference firmware: QTR-1A photoreflectors -> ADC -> framed samples on USB serial.
//
// Protocol version 2 (docs/serial-frame.md), little-endian, CRC-16/CCITT-FALSE over
// everything after the sync bytes:
//   data frame: a5 5a | 0x20|n | seq u16 | t_us u32 | n x u16 counts | crc u16
//   info frame: a5 5a | 0x20 | len u8 | adc_bits u8 | channels u8 | vref_mv u16 |
//               period_us u32 | name_len u8 | board name | crc u16
// The info frame says what the codes mean, so the host never has to be told: it is sent
// at start and every INFO_PERIOD_US.
//
// Wiring: QTR-1A OUT -> A0 (more modules: A1.., raise CHANNELS), VIN -> the board's ADC
// reference (5 V on an Uno, 3.3 V on 3.3 V boards), GND -> GND. Channel c is pin A0 + c.
// Eight modules need eight analog inputs: the Nano (ATmega328P in TQFP, A0-A7); the Uno's
// DIP package has A0-A5 only, and a count above the board's inputs does not compile.
// Boards: the resolution, reference and name come from the boards' own macros below; on an
// Uno/Nano (UART bridge) 1 000 000 baud is exact at 16 MHz; on native-USB boards
// (Leonardo, SAMD, RP2040, Teensy) the baud rate is ignored.
//
// Sampling never waits for the host: a frame that does not fit in the transmit buffer
// is dropped, and the host sees the gap in the sequence number.

#include <Arduino.h>

#ifndef TACTILE_CHANNELS
#define TACTILE_CHANNELS 1
#endif

// What this board's ADC gives. Another board: define all three when compiling, e.g.
// -DTACTILE_ADC_BITS=12 -DTACTILE_VREF_MV=3300 -DTACTILE_BOARD='"esp32"', and make
// setup() switch the ADC to that resolution.
#if defined(TACTILE_ADC_BITS)
#elif defined(ARDUINO_ARCH_AVR)       // Uno, Nano, Mega, Leonardo: 10-bit ADC, AVcc reference
#define TACTILE_ADC_BITS 10
#define TACTILE_BOARD "avr"
#elif defined(ARDUINO_ARCH_RENESAS)   // Uno R4: 5 V like the Uno, 12 bit on request
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "renesas"
#elif defined(ARDUINO_ARCH_SAMD)      // Zero, MKR, Nano 33 IoT: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "samd"
#elif defined(ARDUINO_ARCH_SAM)       // Due: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "sam"
#elif defined(ARDUINO_ARCH_RP2040)    // Raspberry Pi Pico (arduino-pico, mbed): 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "rp2040"
#elif defined(TEENSYDUINO)            // Teensy 3.x/4.x: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "teensy"
#else
#error "Unknown board: define TACTILE_ADC_BITS, TACTILE_VREF_MV and TACTILE_BOARD."
#endif

#ifndef TACTILE_BOARD
#define TACTILE_BOARD "custom"
#endif
#ifndef TACTILE_VREF_MV
#if defined(ARDUINO_ARCH_AVR) || defined(ARDUINO_ARCH_RENESAS)
#define TACTILE_VREF_MV 5000          // a 3.3 V AVR board (Pro Mini 8 MHz): -DTACTILE_VREF_MV=3300
#else
#define TACTILE_VREF_MV 3300
#endif
#endif

static const uint8_t CHANNELS = TACTILE_CHANNELS;  // 1..8, pins A0..A(CHANNELS-1)
static const uint32_t PERIOD_US = 1000;             // 1 kHz
static const uint32_t INFO_PERIOD_US = 250000;      // info frame 4x per second
static const uint32_t BAUD = 1000000;
static const uint8_t VERSION = 2;
static const uint8_t FRAME_SIZE = 11 + 2 * CHANNELS;
static const char BOARD[] = TACTILE_BOARD;
static const uint8_t NAME_LEN = sizeof(BOARD) - 1;
static const uint8_t INFO_PAYLOAD = 9 + NAME_LEN;
static const uint8_t INFO_SIZE = 4 + INFO_PAYLOAD + 2;

static_assert(CHANNELS >= 1 && CHANNELS <= 8, "CHANNELS must be 1..8");
#if defined(NUM_ANALOG_INPUTS)                    // the board's variant says how many pins
static_assert(CHANNELS <= NUM_ANALOG_INPUTS,
              "TACTILE_CHANNELS exceeds this board's analog inputs (NUM_ANALOG_INPUTS); "
              "8 channels need a board with A0-A7 such as the Nano, not the Uno");
#endif

#if defined(ARDUINO_ARCH_AVR) && defined(ADCSRA)
// ADC clock on AVR. The core starts the ADC at F_CPU / 128 (125 kHz at 16 MHz); a
// conversion is 13 ADC clocks (ATmega328P datasheet, "Analog-to-Digital Converter"), about
// 112 us per analogRead with its overhead, so 8 channels would take ~0.9 ms of the 1 ms
// period and leave too little for the CRC and the serial frame. The datasheet asks for a
// 50-200 kHz ADC clock for full 10-bit resolution and allows a faster clock for lower
// resolution (its typical absolute accuracy: 2 LSB at 200 kHz, 4.5 LSB at 1 MHz). So when
// the conversions would take over half the period, the sketch uses F_CPU / 32 (500 kHz,
// ~28 us a read) and accepts the slightly reduced accuracy. Prescaler bits ADPS2:0 in
// ADCSRA: 0b111 = 128, 0b101 = 32. -DTACTILE_ADC_PRESCALER=128 keeps the slow clock.
#ifndef TACTILE_ADC_PRESCALER
#define TACTILE_ADC_PRESCALER (TACTILE_CHANNELS * 112 > 500 ? 32 : 128)
#endif
static_assert(TACTILE_ADC_PRESCALER == 32 || TACTILE_ADC_PRESCALER == 128,
              "TACTILE_ADC_PRESCALER must be 32 or 128");
static const uint8_t ADPS_MASK = (1 << ADPS2) | (1 << ADPS1) | (1 << ADPS0);
static const uint8_t ADPS_BITS =
    TACTILE_ADC_PRESCALER == 32 ? (uint8_t)((1 << ADPS2) | (1 << ADPS0)) : ADPS_MASK;
#endif
static_assert(TACTILE_ADC_BITS >= 1 && TACTILE_ADC_BITS <= 16, "ADC bits must be 1..16");
static_assert(NAME_LEN <= 31, "the board name has at most 31 characters");

static uint16_t seq = 0;
static uint32_t next_us = 0;
static uint32_t next_info_us = 0;

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor.
static uint16_t crc16(const uint8_t *data, uint8_t len) {
  uint16_t crc = 0xFFFF;
  while (len--) {
    crc ^= (uint16_t)(*data++) << 8;
    for (uint8_t bit = 0; bit < 8; bit++) {
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
  }
  return crc;
}

static void put16(uint8_t *p, uint16_t v) { p[0] = v & 0xFF; p[1] = v >> 8; }

static void put32(uint8_t *p, uint32_t v) {
  p[0] = v & 0xFF; p[1] = (v >> 8) & 0xFF; p[2] = (v >> 16) & 0xFF; p[3] = v >> 24;
}

// Send the info frame if it fits now; false means try again on the next loop.
static bool send_info() {
  if (Serial.availableForWrite() < INFO_SIZE) return false;
  uint8_t frame[INFO_SIZE];
  frame[0] = 0xA5;
  frame[1] = 0x5A;
  frame[2] = (uint8_t)(VERSION << 4);              // channel count 0: info frame
  frame[3] = INFO_PAYLOAD;
  frame[4] = TACTILE_ADC_BITS;
  frame[5] = CHANNELS;
  put16(frame + 6, TACTILE_VREF_MV);
  put32(frame + 8, PERIOD_US);
  frame[12] = NAME_LEN;
  for (uint8_t i = 0; i < NAME_LEN; i++) frame[13 + i] = (uint8_t)BOARD[i];
  put16(frame + 4 + INFO_PAYLOAD, crc16(frame + 2, 2 + INFO_PAYLOAD));
  Serial.write(frame, INFO_SIZE);
  return true;
}

void setup() {
  Serial.begin(BAUD);
#if TACTILE_ADC_BITS != 10
  analogReadResolution(TACTILE_ADC_BITS);         // every core above starts at 10 bit
#endif
#if defined(ARDUINO_ARCH_AVR) && defined(ADCSRA)
  ADCSRA = (uint8_t)((ADCSRA & ~ADPS_MASK) | ADPS_BITS);
#endif
  next_us = micros();
  next_info_us = next_us;
}

void loop() {
  const uint32_t now = micros();
  if ((int32_t)(now - next_info_us) >= 0 && send_info()) {
    next_info_us = now + INFO_PERIOD_US;
  }
  // Wait for the next period (wrap-safe unsigned arithmetic).
  if ((int32_t)(now - next_us) < 0) return;
  next_us += PERIOD_US;

  uint8_t frame[FRAME_SIZE];
  const uint32_t t_us = micros();                 // stamp at the conversion
  frame[0] = 0xA5;
  frame[1] = 0x5A;
  frame[2] = (uint8_t)((VERSION << 4) | CHANNELS);
  put16(frame + 3, seq);
  put32(frame + 5, t_us);
  for (uint8_t ch = 0; ch < CHANNELS; ch++) {
    put16(frame + 9 + 2 * ch, (uint16_t)analogRead(A0 + ch));
  }
  put16(frame + 9 + 2 * CHANNELS, crc16(frame + 2, 7 + 2 * CHANNELS));

  // Drop rather than block when the host is not reading fast enough.
  if (Serial.availableForWrite() >= FRAME_SIZE) {
    Serial.write(frame, FRAME_SIZE);
  }
  seq++;                                          // counts sampled frames, sent or not
}
