//! Batch work: a run's work items partitioned across processes ([`shard`]) and the shards'
//! partial reports joined into what one process writes ([`merge`]).

pub mod merge;
pub mod shard;
