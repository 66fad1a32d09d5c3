// The fast virtual board's harness: the Verilated top level, clocked in C++.
//
// It does the per-cycle work of the virtual board and nothing else: it clocks the model, moves
// bytes between queues and the UART pins (8N1, bit edges on whole clock cycles of an exact
// schedule), records the rising edges of tdc_start and aggressor_laser, and shifts sensor
// events out on the bus from a queue of windows read out (bus timing: docs/virtual-board.md).
// The photons are the scene simulator's (Python, numpy): the harness only presents the events
// it was given. Python drives it through the C functions below (ctypes).

#include <cstdint>
#include <deque>
#include <vector>

#include "Vfliss_top.h"
#include "verilated.h"

namespace {

// Clock cycles one event takes on the bus: bus set, strobe from the next cycle for two
// cycles, bus held three more.
constexpr int EVENT_BUS_CYCLES = 6;

struct Event {
    uint16_t timestamp;
    uint8_t address;
    uint8_t collision;
};

struct Edge {
    int64_t cycle;
    int kind;  // 0: tdc_start, 1: aggressor_laser
};

struct Harness {
    VerilatedContext context;
    Vfliss_top* top;
    int64_t cycle = 0;            // rising clock edges so far
    double bit_cycles;            // clock cycles per UART bit

    // UART to the board (uart_rx): bytes waiting, and the character being sent
    std::deque<uint8_t> to_board;
    int tx_bit = -1;              // bit of the character on the pin (-1: idle)
    int64_t tx_origin = 0;        // cycle of the schedule's origin
    int64_t tx_bits = 0;          // bits sent since the origin
    int tx_bits_of_char = 0;
    uint16_t tx_shift = 0;

    // UART from the board (uart_tx)
    std::vector<uint8_t> to_host;
    int64_t rx_start = -1;        // cycle of the start bit's falling edge (-1: idle)
    int rx_bit = 0;
    uint16_t rx_value = 0;
    int framing_errors = 0;
    uint8_t rx_previous = 1;

    // Edges of tdc_start and aggressor_laser
    std::vector<Edge> edges;
    uint8_t start_previous = 0, aggressor_previous = 0;
    int64_t window_cycles = 0;    // a TDC window's conversion range, in cycles
    int64_t last_start = -1;      // cycle of the last tdc_start edge
    bool cut = false;             // the last start came before the previous window's end

    // Sensor bus: windows read out, each a list of events
    std::deque<std::vector<Event>> windows;
    std::vector<Event> current;   // the window being shifted out
    size_t position = 0;          // its next event
    int64_t event_cycle = -1;     // cycle the event on the bus was set (-1: none)
    int64_t busy_drops = 0;
    int64_t presented = 0;
    std::vector<Event> presented_log;
    bool record = false;

    explicit Harness(double bit_cycles_) : bit_cycles(bit_cycles_) {
        top = new Vfliss_top{&context};
        top->clk = 0;
        top->rst = 0;
        top->uart_rx = 1;
        top->eval();
    }
    ~Harness() {
        top->final();
        delete top;
    }

    // One clock cycle: inputs for this edge, the rising edge, then what changed.
    void tick() {
        drive_uart();
        drive_bus();
        top->clk = 1;
        top->eval();
        ++cycle;
        sample();
        top->clk = 0;
        top->eval();
    }

    void drive_uart() {
        if (tx_bit < 0) {
            if (to_board.empty()) return;
            // A new character: 8N1 (start bit 0, data LSB first, stop bit 1)
            if (tx_bits == 0 || cycle > tx_origin + edge_of(tx_bits) + 1) {
                tx_origin = cycle;  // the line was idle: a new schedule
                tx_bits = 0;
            }
            tx_shift = static_cast<uint16_t>((to_board.front() << 1) | 0x200);
            to_board.pop_front();
            tx_bit = 0;
        }
        if (cycle >= tx_origin + edge_of(tx_bits)) {
            top->uart_rx = (tx_shift >> tx_bit) & 1;
            ++tx_bits;
            if (++tx_bit == 10) tx_bit = -1;
        }
    }

    // The cycle the sensor model closes the last start's window: one after its range.
    int64_t window_end() const { return last_start + window_cycles + 1; }

    int64_t edge_of(int64_t bits) const {
        return static_cast<int64_t>(bits * bit_cycles + 0.5);
    }

    void drive_bus() {
        if (event_cycle >= 0) {
            int64_t age = cycle - event_cycle;
            if (age == 1) top->sensor_valid = 1;
            if (age == 3) top->sensor_valid = 0;
            if (age < EVENT_BUS_CYCLES) return;
            event_cycle = -1;
        }
        while (!windows.empty()) {
            // The next window's readout overwrites the buffer
            busy_drops += current.size() - position;
            current = std::move(windows.front());
            windows.pop_front();
            position = 0;
        }
        if (position < current.size()) {
            const Event& event = current[position++];
            top->sensor_timestamp = event.timestamp;
            top->sensor_address = event.address;
            top->sensor_collision = event.collision;
            event_cycle = cycle;
            ++presented;
            if (record) presented_log.push_back(event);
        }
    }

    void sample() {
        if (top->tdc_start && !start_previous) {
            edges.push_back({cycle, 0});
            cut = last_start >= 0 && cycle <= window_end();
            last_start = cycle;
        }
        if (top->aggressor_laser && !aggressor_previous) edges.push_back({cycle, 1});
        start_previous = top->tdc_start;
        aggressor_previous = top->aggressor_laser;
        uint8_t level = top->uart_tx;
        if (rx_start < 0) {
            if (rx_previous && !level) {
                rx_start = cycle;
                rx_bit = 0;
                rx_value = 0;
            }
        } else if (cycle >= rx_start + static_cast<int64_t>((rx_bit + 0.5) * bit_cycles + 0.5)) {
            // The middle of a bit
            rx_value |= static_cast<uint16_t>(level << rx_bit);
            if (++rx_bit == 10) {
                if (rx_value >> 9) to_host.push_back(static_cast<uint8_t>(rx_value >> 1));
                else ++framing_errors;
                rx_start = -1;
            }
        }
        rx_previous = level;
    }
};

}  // namespace

extern "C" {

Harness* fh_new(double bit_cycles) { return new Harness(bit_cycles); }
void fh_free(Harness* h) { delete h; }
int fh_running(Harness* h) { return h->top->running; }
void fh_set_record(Harness* h, int record) { h->record = record != 0; }
void fh_set_window(Harness* h, int64_t cycles) { h->window_cycles = cycles; }

// Run until `until` (a cycle) or, with `stop_on_window`, until the sensor model has a window
// to simulate: a start cut the previous window short, or the last start's window ended.
// Returns the cycles run.
int64_t fh_run(Harness* h, int64_t until, int stop_on_window) {
    int64_t begin = h->cycle;
    size_t edges = h->edges.size();
    while (h->cycle < until) {
        h->tick();
        if (!stop_on_window || h->last_start < 0) continue;
        if (h->cycle == h->window_end()) break;
        if (h->edges.size() != edges) {
            if (h->cut && h->cycle == h->last_start) break;
            edges = h->edges.size();
        }
    }
    return h->cycle - begin;
}

// The level of the top level's rst input from the next cycle on.
void fh_set_reset(Harness* h, int level) { h->top->rst = level != 0; }

void fh_write(Harness* h, const uint8_t* data, int count) {
    h->to_board.insert(h->to_board.end(), data, data + count);
}
int fh_to_board(Harness* h) { return static_cast<int>(h->to_board.size()) + (h->tx_bit >= 0); }

int fh_read(Harness* h, uint8_t* data, int space) {
    int count = static_cast<int>(h->to_host.size()) < space ? h->to_host.size() : space;
    std::copy(h->to_host.begin(), h->to_host.begin() + count, data);
    h->to_host.erase(h->to_host.begin(), h->to_host.begin() + count);
    return count;
}

// Take up to `space` recorded edges, oldest first: cycle and kind of each.
int fh_edges(Harness* h, int64_t* cycles, int32_t* kinds, int space) {
    int count = static_cast<int>(h->edges.size()) < space ? h->edges.size() : space;
    for (int i = 0; i < count; ++i) {
        cycles[i] = h->edges[i].cycle;
        kinds[i] = h->edges[i].kind;
    }
    h->edges.erase(h->edges.begin(), h->edges.begin() + count);
    return count;
}

// fh_run, stopping where the sensor model has a window, then fh_edges: one call where the
// board's loop would make two. The cycles run go to *ran; returns the edges taken.
int fh_run_edges(Harness* h, int64_t until, int64_t* ran, int64_t* cycles, int32_t* kinds,
                 int space) {
    *ran = fh_run(h, until, 1);
    return fh_edges(h, cycles, kinds, space);
}

// A window read out now: its events go on the bus from the next cycle on. Each event is
// packed in a word: timestamp in bits 0-15, address in bits 16-23, collision flag in bit 24.
void fh_window(Harness* h, const uint32_t* events, int count) {
    std::vector<Event> window(count);
    for (int i = 0; i < count; ++i) {
        window[i] = {static_cast<uint16_t>(events[i]), static_cast<uint8_t>(events[i] >> 16),
                     static_cast<uint8_t>(events[i] >> 24)};
    }
    h->windows.push_back(std::move(window));
}

// Counters: 0 events put on the bus, 1 events overwritten in the readout buffer, 2 UART
// framing errors.
int64_t fh_counter(Harness* h, int which) {
    switch (which) {
        case 0: return h->presented;
        case 1: return h->busy_drops;
        default: return h->framing_errors;
    }
}

// Take up to `space` events put on the bus (with fh_set_record).
int fh_presented(Harness* h, uint16_t* timestamps, uint8_t* addresses, uint8_t* collisions,
                 int space) {
    auto& log = h->presented_log;
    int count = static_cast<int>(log.size()) < space ? log.size() : space;
    for (int i = 0; i < count; ++i) {
        timestamps[i] = log[i].timestamp;
        addresses[i] = log[i].address;
        collisions[i] = log[i].collision;
    }
    log.erase(log.begin(), log.begin() + count);
    return count;
}

}  // extern "C"
