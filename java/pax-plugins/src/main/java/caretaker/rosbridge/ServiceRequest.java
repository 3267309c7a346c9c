package caretaker.rosbridge;

import com.google.gson.JsonObject;

/** The request of a service call: a JSON object with the request fields. */
public class ServiceRequest extends JsonWrapper {
    /** An empty request (e.g. for std_srvs/Trigger). */
    public ServiceRequest() {
        super(new JsonObject());
    }

    /** @param json the request fields (copied) */
    public ServiceRequest(JsonObject json) {
        super(json);
    }

    /** @param json the request as JSON text */
    public ServiceRequest(String json) {
        super(json);
    }
}
