// LSD radix sort, serial layout (src/kernels/sort.rs `SortLayout::Serial`): each invocation owns
// a chunk of SERIAL_CHUNK consecutive keys and walks it in order on its own, so neither kernel
// has a workgroup scan, a subgroup operation or a barrier. For devices that run a workgroup on
// one CPU thread (lavapipe): there a barrier turns the whole shader into coroutines and the
// workgroup scans of the cooperative layout cost more than counting the keys (measured: the
// histogram's time halves without them). The histogram table has one row entry per chunk
// (hist[digit * chunks + chunk]), so one exclusive scan of it gives each (digit, chunk) the
// start of its run, as in the cooperative layout; the scatter then moves the chunk's pairs in
// input order from 16 cursors. Same digits and same stability, hence the same result.
// Full chunks read four keys a load; the last, partial chunk one at a time, so nothing past `n`
// is read. CPU twin: src/cpu/sort.rs (`histogram` and `scatter` with a block of SERIAL_CHUNK).

#define SERIAL_CHUNK 512

layout(local_size_x = 64) in;

uint digit_of(uint key) {
    return (key >> pc.shift) & (RADIX - 1);
}

// The keys of chunk `chunk`: the first index and one past the last.
uvec2 chunk_range(uint chunk) {
    uint first = chunk * SERIAL_CHUNK;
    return uvec2(first, min(first + SERIAL_CHUNK, pc.n));
}
