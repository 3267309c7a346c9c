package caretaker.rosbridge;

/** Collects the parts of one fragmented message until all have arrived. Thread-safe. */
final class FragmentBuffer {
    private final String[] parts;
    private int received;

    FragmentBuffer(int total) {
        if (total < 1) {
            throw new IllegalArgumentException("fragment total must be at least 1, got " + total);
        }
        parts = new String[total];
    }

    /**
     * @return the whole message once the last missing part arrived, else null
     */
    synchronized String add(int num, String data) {
        if (num < 0 || num >= parts.length) {
            throw new IllegalArgumentException("fragment " + num + " outside 0.." + (parts.length - 1));
        }
        if (parts[num] == null) {
            parts[num] = data;
            received++;
        }
        return received == parts.length ? String.join("", parts) : null;
    }
}
