package caretaker.rosbridge;

import com.google.gson.JsonObject;

/**
 * The reply to a service call. When {@link #getResult()} is false the call failed in rosbridge
 * (not in the service: a service reports its own failures in its fields, e.g. {@code success});
 * {@link #getError()} then holds the server's text and the values are empty.
 */
public class ServiceResponse extends JsonWrapper {
    private final boolean result;
    private final String error;

    /**
     * A successful response.
     *
     * @param values the response fields (copied)
     */
    public ServiceResponse(JsonObject values) {
        this(values, true, "");
    }

    private ServiceResponse(JsonObject values, boolean result, String error) {
        super(values);
        this.result = result;
        this.error = error;
    }

    /**
     * A failed call.
     *
     * @param error the server's description of the failure
     * @return a response with result false and no values
     */
    public static ServiceResponse failure(String error) {
        return new ServiceResponse(new JsonObject(), false, error);
    }

    /** @return whether rosbridge carried the call out */
    public boolean getResult() {
        return result;
    }

    /** @return the failure text, or "" when the call succeeded */
    public String getError() {
        return error;
    }
}
