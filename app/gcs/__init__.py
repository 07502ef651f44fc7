"""The ground station over MQTT: payloads and topics (``protocol``), settings (``config``), the vehicle's end of
the link (``link.GroundLink``) and the operator's command line (``python -m app.gcs``)."""
