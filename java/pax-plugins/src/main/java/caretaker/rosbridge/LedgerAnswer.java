package caretaker.rosbridge;

import com.google.gson.JsonObject;

/**
 * The outcome of a command sent through the {@link CommandLedger}.
 *
 * @param state what became of it
 * @param response the called service's response when it answered ({@link LedgerState#SUCCEEDED}
 *     or {@link LedgerState#FAILED}), else null
 * @param message why, in words: the service's message, or what the link or the ledger did
 */
public record LedgerAnswer(LedgerState state, JsonObject response, String message) {
    /** Copies the response so the record stays immutable. */
    public LedgerAnswer {
        response = response == null ? null : response.deepCopy();
        message = message == null ? "" : message;
    }

    /** @return a copy of the response, or null */
    @Override
    public JsonObject response() {
        return response == null ? null : response.deepCopy();
    }
}
