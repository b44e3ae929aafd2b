//! Dynamic Allan variance: the streaming F-DAVAR engine, F value and window policies.
