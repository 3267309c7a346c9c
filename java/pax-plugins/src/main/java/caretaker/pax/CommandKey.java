package caretaker.pax;

/**
 * What identifies one command across resends, reconnects and restarts: the run, the instruction
 * number in it, and the attempt (a retry of the instruction is a new attempt, hence a new
 * command). Its string form {@code run/instruction/attempt} (e.g. {@code run-42/3.2/1}) is the
 * habitat's command ledger key: the ledger executes a key at most once.
 *
 * @param runId the run, without {@code /} or blanks
 * @param instruction the instruction number, e.g. {@code 3.2}, without {@code /} or blanks
 * @param attempt 1 for the first attempt, then 2, 3, ...
 */
public record CommandKey(String runId, String instruction, int attempt) {
    /** Checks each part can be told apart in the string form. */
    public CommandKey {
        part("run id", runId);
        part("instruction", instruction);
        if (attempt < 1) {
            throw new IllegalArgumentException("command key attempt must be 1 or more, got " + attempt);
        }
    }

    private static void part(String what, String value) {
        if (value == null || value.isEmpty() || value.chars().anyMatch(c -> c == '/' || Character.isWhitespace(c)
                || Character.isISOControl(c))) {
            throw new IllegalArgumentException("command key " + what + " must be non-empty, without '/' or blanks,"
                    + " got '" + value + "'");
        }
    }

    /**
     * @param text {@code run/instruction/attempt}
     * @return the key
     * @throws IllegalArgumentException not of that form
     */
    public static CommandKey parse(String text) {
        String[] parts = text == null ? new String[0] : text.split("/", -1);
        if (parts.length != 3) {
            throw new IllegalArgumentException("a command key is 'run/instruction/attempt', got '" + text + "'");
        }
        try {
            return new CommandKey(parts[0], parts[1], Integer.parseInt(parts[2]));
        } catch (NumberFormatException e) {
            throw new IllegalArgumentException("command key attempt must be a number, got '" + text + "'", e);
        }
    }

    /** @return {@code run/instruction/attempt} */
    @Override
    public String toString() {
        return runId + "/" + instruction + "/" + attempt;
    }
}
