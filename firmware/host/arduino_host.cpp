// Host runtime of the Arduino shim (Arduino.h): runs the sketch's setup() and loop() with
// micros() from the host's monotonic clock, analogRead() from a stimulus given on stdin and
// Serial writing to a pseudo-terminal, so the host driver reads the real firmware.
//
// Usage: tactile_adc_host --link PATH [--vref VOLTS] [--micros-offset US] [--tx-buffer N]
//   --vref           the board's real ADC reference [V] (what analogRead divides by)
//   --micros-offset  micros() at start (to test the 2^32 wrap)
//   --tx-buffer      transmit buffer [bytes] (64: the Uno's HardwareSerial)
// stdin, one command per line:
//   volts V          every channel at V volts
//   volts CH V       channel CH (0..7) at V volts
//   off V            every channel at V volts while the emitters are off (a modulated
//   off CH V         sketch's off sample); until given, the same as "volts"
//   stats            answer "stats bytes_sent=N blocked_us=N adc_prescaler=N
//                    emitter_pins=N emitter_switches=N" on stdout (adc_prescaler: the AVR
//                    ADC clock divider ADCSRA selects, 0 elsewhere; emitter_pins: pins set
//                    as outputs; emitter_switches: times they went from low to high)
// stdout: "pty /dev/pts/N" once the device is ready. Exits at stdin EOF, SIGINT or SIGTERM.

#include "Arduino.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <string>

HostSerial Serial;
#if defined(ARDUINO_ARCH_AVR)
volatile uint8_t host_adcsra = 0x87;  // ADEN | ADPS2:0 = 0b111, as the core's init() sets
#endif

namespace {

const int kChannels = 8;
double g_vref = 5.0;
double g_volts[kChannels] = {0};
double g_off[kChannels] = {-1, -1, -1, -1, -1, -1, -1, -1};  // < 0: as g_volts
const int kPins = 64;
bool g_output[kPins] = {false};
bool g_high[kPins] = {false};
uint64_t g_switches = 0;
int g_bits = 10;
uint64_t g_micros_offset = 0;
timespec g_start;
int g_master = -1;
uint8_t g_tx[4096];
size_t g_tx_capacity = 64;
size_t g_tx_len = 0;
uint64_t g_bytes_sent = 0;
uint64_t g_blocked_us = 0;
std::string g_stdin;
volatile sig_atomic_t g_stop = 0;

uint64_t elapsed_us() {
  timespec now;
  clock_gettime(CLOCK_MONOTONIC, &now);
  return (uint64_t)(now.tv_sec - g_start.tv_sec) * 1000000u +
         (uint64_t)((now.tv_nsec - g_start.tv_nsec) / 1000);
}

void pause_us(long us) {
  timespec t = {0, us * 1000};
  nanosleep(&t, nullptr);
}

// Move what the pseudo-terminal accepts now out of the transmit buffer.
void drain() {
  while (g_tx_len > 0) {
    ssize_t n = ::write(g_master, g_tx, g_tx_len);
    if (n <= 0) return;  // EAGAIN: the host is not reading
    memmove(g_tx, g_tx + n, g_tx_len - (size_t)n);
    g_tx_len -= (size_t)n;
    g_bytes_sent += (uint64_t)n;
  }
}

// The ADC clock divider the sketch selected (ATmega328P ADPS2:0: 0 and 1 are both 2).
unsigned adc_prescaler() {
#if defined(ARDUINO_ARCH_AVR)
  const unsigned bits = host_adcsra & 0x07u;
  return bits == 0 ? 2u : 1u << bits;
#else
  return 0;
#endif
}

void run_command(const std::string &line) {
  char word[16];
  double a = 0, b = 0;
  int n = sscanf(line.c_str(), "%15s %lf %lf", word, &a, &b);
  if (n >= 1 && strcmp(word, "stats") == 0) {
    int outputs = 0;
    for (int pin = 0; pin < kPins; pin++) outputs += g_output[pin] ? 1 : 0;
    printf("stats bytes_sent=%llu blocked_us=%llu adc_prescaler=%u emitter_pins=%d "
           "emitter_switches=%llu\n", (unsigned long long)g_bytes_sent,
           (unsigned long long)g_blocked_us, adc_prescaler(), outputs,
           (unsigned long long)g_switches);
  } else if (n == 2 && strcmp(word, "volts") == 0) {
    for (int ch = 0; ch < kChannels; ch++) g_volts[ch] = a;
  } else if (n == 3 && strcmp(word, "volts") == 0 && a >= 0 && a < kChannels) {
    g_volts[(int)a] = b;
  } else if (n == 2 && strcmp(word, "off") == 0) {
    for (int ch = 0; ch < kChannels; ch++) g_off[ch] = a;
  } else if (n == 3 && strcmp(word, "off") == 0 && a >= 0 && a < kChannels) {
    g_off[(int)a] = b;
  } else {
    printf("error unknown command '%s'; use: volts V, volts CH V, off V, off CH V, stats\n",
           line.c_str());
  }
  fflush(stdout);
}

void poll_stdin() {
  char buf[512];
  for (;;) {
    ssize_t n = read(STDIN_FILENO, buf, sizeof buf);
    if (n == 0) {
      g_stop = 1;  // the controlling process is gone
      return;
    }
    if (n < 0) return;  // EAGAIN
    g_stdin.append(buf, (size_t)n);
    size_t end;
    while ((end = g_stdin.find('\n')) != std::string::npos) {
      run_command(g_stdin.substr(0, end));
      g_stdin.erase(0, end + 1);
    }
  }
}

void on_signal(int) { g_stop = 1; }

[[noreturn]] void usage(const char *why) {
  fprintf(stderr, "tactile_adc_host: %s\nusage: tactile_adc_host --link PATH [--vref VOLTS] "
          "[--micros-offset US] [--tx-buffer BYTES]\n", why);
  exit(2);
}

}  // namespace

uint32_t micros() { return (uint32_t)(g_micros_offset + elapsed_us()); }

uint32_t millis() { return (uint32_t)((g_micros_offset + elapsed_us()) / 1000u); }

void delayMicroseconds(unsigned int us) { pause_us((long)us); }

void analogReadResolution(int bits) { g_bits = bits < 1 ? 1 : bits > 16 ? 16 : bits; }

void pinMode(uint8_t pin, uint8_t mode) {
  if (pin < kPins) g_output[pin] = mode == OUTPUT;
}

void digitalWrite(uint8_t pin, uint8_t level) {
  if (pin >= kPins) return;
  if (level && !g_high[pin] && g_output[pin]) g_switches++;
  g_high[pin] = level != 0;
}

// The emitters are on while any output pin is high (a sketch without them: always on).
static bool emitters_on() {
  bool any_output = false;
  for (int pin = 0; pin < kPins; pin++) {
    if (g_output[pin] && g_high[pin]) return true;
    any_output = any_output || g_output[pin];
  }
  return !any_output;
}

int analogRead(uint8_t pin) {
  int ch = pin >= A0 ? pin - A0 : pin;
  if (ch >= kChannels) return 0;
  const long full = (1L << g_bits) - 1;
  const double volts = emitters_on() || g_off[ch] < 0 ? g_volts[ch] : g_off[ch];
  long code = (long)floor(volts / g_vref * (double)(1L << g_bits));
  return (int)(code < 0 ? 0 : code > full ? full : code);
}

void HostSerial::begin(unsigned long) {}

int HostSerial::availableForWrite() {
  drain();
  return (int)(g_tx_capacity - 1 - g_tx_len);  // a ring buffer keeps one slot free
}

size_t HostSerial::write(const uint8_t *data, size_t size) {
  for (size_t i = 0; i < size; i++) {
    while (g_tx_len >= g_tx_capacity - 1 && !g_stop) {  // full: wait, as the real UART does
      drain();
      if (g_tx_len >= g_tx_capacity - 1) {
        pause_us(50);
        g_blocked_us += 50;
      }
    }
    g_tx[g_tx_len++] = data[i];
  }
  drain();
  return size;
}

size_t HostSerial::write(uint8_t byte) { return write(&byte, 1); }

int main(int argc, char **argv) {
  const char *link = nullptr;
  for (int i = 1; i < argc; i++) {
    std::string arg = argv[i];
    if (i + 1 >= argc) usage(("missing value after " + arg).c_str());
    const char *value = argv[++i];
    char *end = nullptr;
    if (arg == "--link") {
      link = value;
    } else if (arg == "--vref") {
      g_vref = strtod(value, &end);
      if (*end || !(g_vref > 0)) usage("--vref must be a positive voltage");
    } else if (arg == "--micros-offset") {
      g_micros_offset = strtoull(value, &end, 10);
      if (*end) usage("--micros-offset must be an integer");
    } else if (arg == "--tx-buffer") {
      g_tx_capacity = strtoul(value, &end, 10);
      if (*end || g_tx_capacity < 2 || g_tx_capacity > sizeof g_tx) {
        usage("--tx-buffer must be 2..4096 bytes");
      }
    } else {
      usage(("unknown option " + arg).c_str());
    }
  }
  if (link == nullptr) usage("--link is required");

  int slave = -1;
  char name[128];
  if (openpty(&g_master, &slave, name, nullptr, nullptr) != 0) {
    perror("tactile_adc_host: openpty");
    return 1;
  }
  termios raw;
  tcgetattr(slave, &raw);
  cfmakeraw(&raw);  // binary frames pass untouched
  tcsetattr(slave, TCSANOW, &raw);
  fcntl(g_master, F_SETFL, fcntl(g_master, F_GETFL) | O_NONBLOCK);
  fcntl(STDIN_FILENO, F_SETFL, fcntl(STDIN_FILENO, F_GETFL) | O_NONBLOCK);
  // Our slave fd stays open so the host can close and reopen the port without EIO.
  std::string tmp = std::string(link) + ".tmp";
  unlink(tmp.c_str());
  if (symlink(name, tmp.c_str()) != 0 || rename(tmp.c_str(), link) != 0) {
    fprintf(stderr, "tactile_adc_host: cannot create the link %s: %s\n", link, strerror(errno));
    return 1;
  }
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);
  signal(SIGPIPE, SIG_IGN);
  printf("pty %s\n", name);
  fflush(stdout);

  clock_gettime(CLOCK_MONOTONIC, &g_start);
  setup();
  while (!g_stop) {
    poll_stdin();
    drain();
    loop();
    pause_us(100);  // loop() polls micros(); 10 kHz is plenty for a 1 kHz sketch
  }
  unlink(link);
  close(slave);
  close(g_master);
  return 0;
}
