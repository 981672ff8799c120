// Troupe.cs: C# bindings of troupe's C ABI (include/troupe.h) for .NET, Mono and Unity.
//
//   using (var model = Troupe.Model.Load("armflow-demo"))
//   using (var session = model.CreateSession(new Troupe.SessionOptions { Seed = 7 }))
//   {
//       session.SetCondition("mirror");
//       session.SetJointsFormat(Troupe.JointsFormat.Default);      // metres, Y up, 30 fps
//       var partner = new float[session.JointsReadyAfter(1) * 22 * 3];
//       int ready = session.StepJoints(actorFrame, 1, partner);   // [22 * 3] per frame in and out
//   }
//
// One file, C# 7.3, no unsafe code: drop it into a project with the native library (libtroupe.so,
// troupe.dll or libtroupe.dylib) where the runtime finds it (Unity: Plugins/x86_64/). Arrays go
// to the library pinned, never copied; no callback crosses from native code into managed code.
//
// Ownership and threading follow the C ABI: a Model may be shared by any number of threads and
// sessions keep it alive; a Session is used by one thread at a time (a second thread gets
// BusyException). Model and Session own their native handles through SafeHandles: Dispose them
// (or let the finalizer) and they are freed once. Every failed call throws the TroupeException
// subclass of its status code with the library's message; a failed step leaves the session as
// it was. Arguments the binding can check itself (null, array lengths) throw
// ArgumentException and ArgumentNullException before any native call.
using System;
using System.Collections.Generic;
using System.Runtime.InteropServices;
using System.Text;

// The binding's release: the library's version it was written for (a test checks they match).
[assembly: System.Reflection.AssemblyVersion("0.2.0")]
[assembly: System.Reflection.AssemblyInformationalVersion("0.2.0")]

namespace Troupe
{
    /// <summary>A troupe call failed: <see cref="Status"/> is the TROUPE_ERR_* code and
    /// <see cref="StatusName"/> its name; the message is the library's.</summary>
    public class TroupeException : Exception
    {
        /// <summary>The TROUPE_ERR_* status code.</summary>
        public int Status { get; }
        /// <summary>The symbolic name of <see cref="Status"/>, e.g. "TROUPE_ERR_INVALID_ARG".</summary>
        public string StatusName { get; }

        /// <summary>An exception for <paramref name="status"/> with the library's message.</summary>
        public TroupeException(int status, string name, string message) : base(name + ": " + message)
        {
            Status = status;
            StatusName = name;
        }

        /// <summary>The exception class of a status code (a code this binding does not know,
        /// from a newer library, is a plain TroupeException carrying it).</summary>
        internal static TroupeException FromStatus(int status, string message)
        {
            string name = Native.Utf8(Native.troupe_status_name(status)) ?? "TROUPE_ERR_UNKNOWN";
            switch (status)
            {
                case 1: return new NullArgumentException(status, name, message);
                case 2: return new InvalidArgumentException(status, name, message);
                case 3: return new ShapeMismatchException(status, name, message);
                case 4: return new BufferTooSmallException(status, name, message);
                case 5: return new IoException(status, name, message);
                case 6: return new ModelException(status, name, message);
                case 7: return new InferenceException(status, name, message);
                case 8: return new PoisonedException(status, name, message);
                case 9: return new PanicException(status, name, message);
                case 10: return new BusyException(status, name, message);
                case 11: return new CancelledException(status, name, message);
                case 12: return new UnsupportedException(status, name, message);
                default: return new TroupeException(status, name, message);
            }
        }
    }

    /// <summary>TROUPE_ERR_NULL_ARG: a required pointer was NULL (a binding bug).</summary>
    public sealed class NullArgumentException : TroupeException { internal NullArgumentException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_INVALID_ARG: a value out of range, non-finite or unknown.</summary>
    public sealed class InvalidArgumentException : TroupeException { internal InvalidArgumentException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_SHAPE: an array of the wrong size for the model.</summary>
    public sealed class ShapeMismatchException : TroupeException { internal ShapeMismatchException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_BUFFER_TOO_SMALL: an output array could not hold the result.</summary>
    public sealed class BufferTooSmallException : TroupeException { internal BufferTooSmallException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_IO: a file could not be read or written.</summary>
    public sealed class IoException : TroupeException { internal IoException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_MODEL: the bundle is corrupt, of another version, or not loadable.</summary>
    public sealed class ModelException : TroupeException { internal ModelException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_INFERENCE: a network failed; the session is as it was.</summary>
    public sealed class InferenceException : TroupeException { internal InferenceException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_POISONED: an earlier panic left the object unusable until reset.</summary>
    public sealed class PoisonedException : TroupeException { internal PoisonedException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_PANIC: the library caught an internal panic (a bug in troupe).</summary>
    public sealed class PanicException : TroupeException { internal PanicException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_BUSY: another thread is using this session.</summary>
    public sealed class BusyException : TroupeException { internal BusyException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_CANCELLED: a progress callback stopped the call.</summary>
    public sealed class CancelledException : TroupeException { internal CancelledException(int s, string n, string m) : base(s, n, m) { } }
    /// <summary>TROUPE_ERR_UNSUPPORTED: the bundle's family does not offer this call.</summary>
    public sealed class UnsupportedException : TroupeException { internal UnsupportedException(int s, string n, string m) : base(s, n, m) { } }

    /// <summary>Options of a new session; a field left null takes the bundle's default.</summary>
    public sealed class SessionOptions
    {
        /// <summary>Seed of the session's noise.</summary>
        public ulong Seed;
        /// <summary>Sampling steps per token.</summary>
        public uint? Steps;
        /// <summary>Classifier-free guidance scale.</summary>
        public float? CfgScale;
        /// <summary>Tokens the key/value cache keeps.</summary>
        public uint? ContextCapacity;
    }

    /// <summary>Units of joint positions.</summary>
    public enum Units : uint { Metres = 0, Centimetres = 1, Millimetres = 2, Inches = 3 }
    /// <summary>The up axis of joint positions.</summary>
    public enum UpAxis : uint { Y = 0, Z = 1 }
    /// <summary>Handedness of the caller's axes.</summary>
    public enum Handedness : uint { Right = 0, Left = 1 }

    /// <summary>How the caller measures joint positions (troupe_joints_format).</summary>
    public struct JointsFormat
    {
        /// <summary>Units of positions.</summary>
        public Units Units;
        /// <summary>The up axis.</summary>
        public UpAxis Up;
        /// <summary>Handedness.</summary>
        public Handedness Handedness;
        /// <summary>Frames per second of the caller's stream (resampled to the model's).</summary>
        public float Fps;

        /// <summary>Metres, Y up, right-handed, 30 fps (Unity: use Handedness.Left).</summary>
        public static JointsFormat Default
        {
            get { return new JointsFormat { Units = Units.Metres, Up = UpAxis.Y, Handedness = Handedness.Right, Fps = 30f }; }
        }

        internal Native.JointsFormatC ToC()
        {
            var c = new Native.JointsFormatC();
            Native.Check(Native.troupe_joints_format_init(ref c, (UIntPtr)Marshal.SizeOf(typeof(Native.JointsFormatC))));
            c.units = (uint)Units;
            c.up_axis = (uint)Up;
            c.handedness = (uint)Handedness;
            c.fps = Fps;
            return c;
        }

        internal static JointsFormat FromC(Native.JointsFormatC c)
        {
            return new JointsFormat { Units = (Units)c.units, Up = (UpAxis)c.up_axis, Handedness = (Handedness)c.handedness, Fps = c.fps };
        }
    }

    /// <summary>Options of a whole ARFlow reaction (troupe_arflow_options); a field left null
    /// takes the bundle's default.</summary>
    public sealed class ArflowOptions
    {
        /// <summary>The seed of the run's noise.</summary>
        public ulong Seed;
        /// <summary>Sampler steps.</summary>
        public uint? Steps;
        /// <summary>Penetration guidance's scale (0: none).</summary>
        public float? Guidance;
    }

    /// <summary>Options of ARMFlow's official clip loop (troupe_armflow_clip_options).</summary>
    public sealed class ClipOptions
    {
        /// <summary>The seed of the run's noise.</summary>
        public ulong Seed;
        /// <summary>Solver steps per token.</summary>
        public uint? Steps;
        /// <summary>Classifier-free guidance scale.</summary>
        public float? CfgScale;
    }

    /// <summary>A loaded bundle. Thread-safe; sessions keep it alive.</summary>
    public sealed class Model : IDisposable
    {
        internal readonly ModelHandle Handle;

        private Model(ModelHandle handle) { Handle = handle; }

        /// <summary>The library's version, e.g. "0.2.0".</summary>
        public static string Version { get { return Native.Utf8(Native.troupe_version_string()); } }
        /// <summary>The C ABI version the library speaks (this binding needs 1).</summary>
        public static uint AbiVersion { get { return Native.troupe_abi_version(); } }

        /// <summary>Loads a bundle directory or archive file.</summary>
        public static Model Load(string path)
        {
            if (path == null) throw new ArgumentNullException("path");
            Native.CheckAbi();
            ModelHandle handle;
            Native.Check(Native.troupe_model_load_file(Native.Utf8Z(path), out handle));
            return new Model(handle);
        }

        /// <summary>Loads a bundle archive from memory (the bytes are copied).</summary>
        public static Model LoadMemory(byte[] archive)
        {
            if (archive == null) throw new ArgumentNullException("archive");
            Native.CheckAbi();
            ModelHandle handle;
            Native.Check(Native.troupe_model_load_memory(archive, (UIntPtr)archive.Length, out handle));
            return new Model(handle);
        }

        /// <summary>Floats per frame of the model's features.</summary>
        public int FrameDim { get { return (int)Native.troupe_model_frame_dim(Live()); } }
        /// <summary>Frames per second of the model.</summary>
        public int Fps { get { return (int)Native.troupe_model_fps(Live()); } }
        /// <summary>The family: "armflow", "umf", "magnet" or "arflow".</summary>
        public string Family { get { return Native.Utf8(Native.troupe_model_family(Live())); } }
        /// <summary>Frames per token.</summary>
        public int FramesPerToken { get { return (int)Native.troupe_model_frames_per_token(Live()); } }

        /// <summary>The names of the model's conditions (the demo model: mirror, follow, keep-away).</summary>
        public IList<string> ConditionLabels
        {
            get
            {
                var h = Live();
                var labels = new List<string>();
                ulong n = (ulong)Native.troupe_model_condition_label_count(h);
                for (ulong i = 0; i < n; i++)
                    labels.Add(Native.Utf8(Native.troupe_model_condition_label(h, (UIntPtr)i)));
                return labels;
            }
        }

        /// <summary>A new stream of this model.</summary>
        public Session CreateSession(SessionOptions options = null)
        {
            var h = Live();
            var opt = new Native.SessionOptionsC();
            Native.Check(Native.troupe_session_options_init(h, ref opt, (UIntPtr)Marshal.SizeOf(typeof(Native.SessionOptionsC))));
            if (options != null)
            {
                opt.seed = options.Seed;
                if (options.Steps.HasValue) opt.steps = options.Steps.Value;
                if (options.CfgScale.HasValue) opt.cfg_scale = options.CfgScale.Value;
                if (options.ContextCapacity.HasValue) opt.context_capacity = options.ContextCapacity.Value;
            }
            SessionHandle session;
            Native.Check(Native.troupe_session_new(h, ref opt, out session));
            session.HoldModel(h);
            return new Session(session, FrameDim);
        }

        /// <summary>A stream that goes on exactly where <see cref="Session.Snapshot"/> saved it,
        /// bit for bit; the snapshot must come from this model (a damaged or foreign one throws
        /// InvalidArgumentException).</summary>
        public Session Restore(byte[] snapshot)
        {
            if (snapshot == null) throw new ArgumentNullException("snapshot");
            var h = Live();
            SessionHandle session;
            Native.Check(Native.troupe_session_restore(h, snapshot, (UIntPtr)snapshot.Length, out session));
            session.HoldModel(h);
            return new Session(session, FrameDim);
        }

        /// <summary><see cref="Restore"/> of a snapshot sealed with <paramref name="key"/>
        /// (<see cref="Seal"/>): a snapshot edited, or sealed with another key, throws
        /// InvalidArgumentException.</summary>
        public Session RestoreSealed(byte[] sealedSnapshot, byte[] key)
        {
            if (sealedSnapshot == null) throw new ArgumentNullException("sealedSnapshot");
            if (key == null) throw new ArgumentNullException("key");
            var h = Live();
            SessionHandle session;
            Native.Check(Native.troupe_session_restore_sealed(h, sealedSnapshot, (UIntPtr)sealedSnapshot.Length, key,
                (UIntPtr)key.Length, out session));
            session.HoldModel(h);
            return new Session(session, FrameDim);
        }

        /// <summary>A snapshot sealed with <paramref name="key"/> (HMAC-SHA-256, docs/SNAPSHOTS.md),
        /// for storage the caller does not trust.</summary>
        public static byte[] Seal(byte[] snapshot, byte[] key)
        {
            if (snapshot == null) throw new ArgumentNullException("snapshot");
            if (key == null) throw new ArgumentNullException("key");
            Native.CheckAbi();
            UIntPtr size;
            Native.Check(Native.troupe_snapshot_seal(snapshot, (UIntPtr)snapshot.Length, key, (UIntPtr)key.Length, null,
                UIntPtr.Zero, out size));
            var sealedBytes = new byte[(int)size];
            Native.Check(Native.troupe_snapshot_seal(snapshot, (UIntPtr)snapshot.Length, key, (UIntPtr)key.Length,
                sealedBytes, size, out size));
            return sealedBytes;
        }

        /// <summary>Frames of latency of the feature stream, and of the joint stream
        /// (StepJoints) which adds its motion stages'.</summary>
        public int LatencyFrames { get { return (int)Native.troupe_model_latency_frames(Live()); } }
        /// <inheritdoc cref="LatencyFrames"/>
        public int JointsLatencyFrames { get { return (int)Native.troupe_model_joints_latency_frames(Live()); } }
        /// <summary>Width of one latent token (0 where the family has none).</summary>
        public int LatentDim { get { return (int)Native.troupe_model_latent_dim(Live()); } }
        /// <summary>Frames of one generated clip (clip-mode families; 0 otherwise).</summary>
        public int ClipFrames { get { return (int)Native.troupe_model_clip_frames(Live()); } }
        /// <summary>Whether the model turns text prompts into conditions itself
        /// (<see cref="Session.SetPrompt"/>).</summary>
        public bool TakesPrompts { get { return Native.troupe_model_takes_prompts(Live()) != UIntPtr.Zero; } }
        /// <summary>The library's version as one number: (major &lt;&lt; 16) | (minor &lt;&lt; 8) | patch.</summary>
        public static uint VersionNumber { get { return Native.troupe_version_number(); } }
        /// <summary>Threads for matrix products, process-wide (0: every core).</summary>
        public static int ComputeThreads
        {
            get { return (int)Native.troupe_compute_threads(); }
            set
            {
                if (value < 0) throw new ArgumentOutOfRangeException("value");
                Native.Check(Native.troupe_set_compute_threads((UIntPtr)value));
            }
        }
        /// <summary>Threads that load a bundle's graphs, process-wide (0: the default).</summary>
        public static int LoadThreads
        {
            get { return (int)Native.troupe_load_threads(); }
            set
            {
                if (value < 0) throw new ArgumentOutOfRangeException("value");
                Native.troupe_set_load_threads((UIntPtr)value);
            }
        }

        /// <summary>ARFlow's whole reaction to <paramref name="frames"/> actor frames (frames *
        /// 262 features): the reactor's frames, as many. Other families throw
        /// UnsupportedException.</summary>
        public float[] ArflowGenerate(float[] actor, int frames, ArflowOptions options = null)
        {
            if (actor == null) throw new ArgumentNullException("actor");
            if (frames < 1 || (long)frames * FrameDim > actor.Length)
                throw new ArgumentException("actor holds fewer than " + frames + " frames", "actor");
            var h = Live();
            var c = new Native.ArflowOptionsC();
            Native.Check(Native.troupe_arflow_options_init(h, ref c, (UIntPtr)Marshal.SizeOf(typeof(Native.ArflowOptionsC))));
            if (options != null)
            {
                c.seed = options.Seed;
                if (options.Steps.HasValue) c.steps = options.Steps.Value;
                if (options.Guidance.HasValue) c.guidance = options.Guidance.Value;
            }
            var out_ = new float[frames * FrameDim];
            Native.Check(Native.troupe_arflow_generate(h, ref c, actor, (UIntPtr)frames, out_, (UIntPtr)frames));
            return out_;
        }

        /// <summary>ARMFlow's official clip loop: <paramref name="frames"/> actor frames (1 to
        /// ClipFrames) in, the reactor's ClipFrames frames out; <paramref name="condition"/> null
        /// for the null condition. Other families throw UnsupportedException.</summary>
        public float[] ArmflowClip(float[] actor, int frames, float[] condition = null, ClipOptions options = null)
        {
            if (actor == null) throw new ArgumentNullException("actor");
            if (frames < 1 || (long)frames * FrameDim > actor.Length)
                throw new ArgumentException("actor holds fewer than " + frames + " frames", "actor");
            var h = Live();
            var c = new Native.ClipOptionsC();
            Native.Check(Native.troupe_armflow_clip_options_init(h, ref c, (UIntPtr)Marshal.SizeOf(typeof(Native.ClipOptionsC))));
            if (options != null)
            {
                c.seed = options.Seed;
                if (options.Steps.HasValue) c.steps = options.Steps.Value;
                if (options.CfgScale.HasValue) c.cfg_scale = options.CfgScale.Value;
            }
            var out_ = new float[ClipFrames * FrameDim];
            Native.Check(Native.troupe_armflow_clip_generate_with_options(h, ref c, actor, (UIntPtr)frames, condition,
                (UIntPtr)(condition == null ? 0 : condition.Length), IntPtr.Zero, out_, (UIntPtr)out_.Length, null, UIntPtr.Zero));
            return out_;
        }

        /// <summary>The model's identity: the SHA-256 of its bundle's files (32 bytes).</summary>
        public byte[] Identity
        {
            get
            {
                var id = new byte[32];
                Native.Check(Native.troupe_model_identity(Live(), id));
                return id;
            }
        }

        // Disposal is tracked here: a SafeHandle that sessions still reference is not yet closed.
        private bool disposed;

        internal ModelHandle Live()
        {
            if (disposed || Handle.IsInvalid) throw new ObjectDisposedException("Troupe.Model");
            return Handle;
        }

        /// <summary>Releases this reference (sessions keep the model alive).</summary>
        public void Dispose()
        {
            disposed = true;
            Handle.Dispose();
        }
    }

    /// <summary>What only an ARMFlow stream takes, as Session.Armflow.</summary>
    public sealed class ArmflowSession
    {
        private readonly Session session;
        internal ArmflowSession(Session session) { this.session = session; }

        /// <summary>Recentring (off with enabled false): before each token, when the actor's root
        /// is more than distance metres from the networks' centre, the centre moves to it and the
        /// networks' state is rebuilt from the last 8 tokens; output stays in the stream's
        /// frame.</summary>
        public void SetRecentring(bool enabled, float distance = 1.0f)
        {
            Native.Check(Native.troupe_armflow_session_set_recentring(session.Handle(), enabled ? 1 : 0, distance));
        }
    }

    /// <summary>What only a MAGNet live partner takes, as Session.Magnet (before the first step
    /// or after a reset).</summary>
    public sealed class MagnetSession
    {
        private readonly Session session;
        internal MagnetSession(Session session) { this.session = session; }

        /// <summary>The partner's opening frames: <paramref name="frames"/> frames of FrameDim
        /// (145) floats each, row-major.</summary>
        public void SetPartnerOpening(float[] opening, int frames)
        {
            if (opening == null) throw new ArgumentNullException("opening");
            if (frames < 0 || (long)frames * session.FrameDim > opening.Length)
                throw new ArgumentException("opening holds fewer than " + frames + " frames of " + session.FrameDim + " floats", "frames");
            Native.Check(Native.troupe_magnet_session_set_partner_opening(session.Handle(), opening, (UIntPtr)frames));
        }

        /// <summary>Send each chunk's frames as soon as they are generated (lower latency).</summary>
        public void SetEarlyEmission(bool early)
        {
            Native.Check(Native.troupe_magnet_session_set_early_emission(session.Handle(), early ? 1 : 0));
        }

        /// <summary>The sampling configuration the partner runs: a released name or JSON.</summary>
        public void SetLiveConfig(string config)
        {
            if (config == null) throw new ArgumentNullException("config");
            Native.Check(Native.troupe_magnet_session_set_live_config(session.Handle(), Native.Utf8Z(config)));
        }
    }

    /// <summary>One stream: an ARMFlow reactor answering an actor, an ARFlow online stream, or a
    /// MAGNet live partner answering a user. One thread at a time.</summary>
    public sealed class Session : IDisposable
    {
        private readonly SessionHandle handle;
        private readonly int frameDim;

        internal Session(SessionHandle handle, int frameDim)
        {
            this.handle = handle;
            this.frameDim = frameDim;
        }

        private bool disposed;

        private SessionHandle Live()
        {
            if (disposed || handle.IsInvalid) throw new ObjectDisposedException("Troupe.Session");
            return handle;
        }

        /// <summary>Feeds <paramref name="actorFrames"/> frames of actor features (FrameDim floats
        /// each) and writes the reactor frames that are ready into <paramref name="output"/>
        /// (its length a multiple of FrameDim); returns how many frames it wrote.</summary>
        public int Step(float[] actor, int actorFrames, float[] output)
        {
            int dim = frameDim;
            CheckFrames(actor, "actor", actorFrames, dim);
            if (output == null) throw new ArgumentNullException("output");
            UIntPtr written;
            Native.Check(Native.troupe_session_step(Live(), actor, (UIntPtr)actorFrames, output,
                (UIntPtr)(output.Length / dim), out written));
            return (int)written;
        }

        /// <summary>How `StepJoints` reads actor positions; forgets the joint stream's frames.</summary>
        public void SetJointsFormat(JointsFormat format)
        {
            var c = format.ToC();
            Native.Check(Native.troupe_session_set_joints_format(Live(), ref c));
        }

        /// <summary>How many reactor poses a `StepJoints` of <paramref name="actorFrames"/>
        /// frames would return now: size its output array with it.</summary>
        public int JointsReadyAfter(int actorFrames)
        {
            if (actorFrames < 0) throw new ArgumentOutOfRangeException("actorFrames");
            UIntPtr n;
            Native.Check(Native.troupe_session_joints_ready_after(Live(), (UIntPtr)actorFrames, out n));
            return (int)n;
        }

        /// <summary>Feeds <paramref name="actorFrames"/> frames of actor joint positions
        /// ([22][3] floats each, as SetJointsFormat said) and writes the reactor poses that are
        /// ready into <paramref name="positions"/> (22 * 3 floats per pose, in the caller's
        /// world); returns how many poses it wrote.</summary>
        public int StepJoints(float[] actor, int actorFrames, float[] positions)
        {
            return StepJoints(actor, actorFrames, positions, null);
        }

        /// <summary>StepJoints that also writes each pose's joint rotations into
        /// <paramref name="rotations"/> (22 * 4 floats per pose: each joint's local rotation
        /// relative to its parent, w x y z, in the caller's axes), what a Humanoid rig is driven
        /// with; null writes none.</summary>
        public int StepJoints(float[] actor, int actorFrames, float[] positions, float[] rotations)
        {
            CheckFrames(actor, "actor", actorFrames, Native.Joints * 3);
            if (positions == null) throw new ArgumentNullException("positions");
            int capacity = positions.Length / (Native.Joints * 3);
            if (rotations != null) capacity = Math.Min(capacity, rotations.Length / (Native.Joints * 4));
            var pinned = GCHandle.Alloc(positions, GCHandleType.Pinned);
            var pinnedRotations = rotations != null ? GCHandle.Alloc(rotations, GCHandleType.Pinned) : default(GCHandle);
            try
            {
                var buffers = new Native.PoseBuffersC
                {
                    positions = pinned.AddrOfPinnedObject(),
                    positions_len = (UIntPtr)positions.Length,
                };
                if (rotations != null)
                {
                    buffers.rotations = pinnedRotations.AddrOfPinnedObject();
                    buffers.rotations_len = (UIntPtr)rotations.Length;
                }
                UIntPtr written;
                Native.Check(Native.troupe_session_step_joints(Live(), actor, (UIntPtr)actorFrames, ref buffers,
                    (UIntPtr)capacity, out written));
                return (int)written;
            }
            finally
            {
                pinned.Free();
                if (rotations != null) pinnedRotations.Free();
            }
        }

        /// <summary>Selects one of the model's named conditions (see Model.ConditionLabels).</summary>
        public void SetCondition(string label)
        {
            if (label == null) throw new ArgumentNullException("label");
            var session = Live();
            // The session holds a reference to its model's handle: valid even after Model.Dispose.
            IntPtr m = session.Model;
            var condition = new float[(int)Native.troupe_model_condition_dim(m)];
            Native.Check(Native.troupe_model_condition_for_label(m, Native.Utf8Z(label), condition, (UIntPtr)condition.Length));
            Native.Check(Native.troupe_session_set_condition(session, condition, (UIntPtr)condition.Length));
        }

        /// <summary>Solver steps per token from now on (1 to the library's limit).</summary>
        public void SetSteps(uint steps) { Native.Check(Native.troupe_session_set_steps(Live(), steps)); }
        /// <summary>Classifier-free guidance scale from now on (finite, 0 to 100).</summary>
        public void SetCfgScale(float scale) { Native.Check(Native.troupe_session_set_cfg_scale(Live(), scale)); }
        /// <summary>Conditions the stream on a text prompt (models with TakesPrompts).</summary>
        public void SetPrompt(string prompt)
        {
            if (prompt == null) throw new ArgumentNullException("prompt");
            Native.Check(Native.troupe_session_set_prompt(Live(), Native.Utf8Z(prompt)));
        }
        /// <summary>Exactly how many frames a Step of <paramref name="actorFrames"/> frames would
        /// return now.</summary>
        public int OutputFrames(int actorFrames)
        {
            if (actorFrames < 0) throw new ArgumentOutOfRangeException("actorFrames");
            UIntPtr n;
            Native.Check(Native.troupe_session_output_frames(Live(), (UIntPtr)actorFrames, out n));
            return (int)n;
        }

        /// <summary>Sets the seed of the session's noise from now on.</summary>
        public void SetSeed(ulong seed) { Native.Check(Native.troupe_session_set_seed(Live(), seed)); }

        /// <summary>Starts the stream again (same options).</summary>
        public void Reset() { Native.Check(Native.troupe_session_reset(Live())); }

        /// <summary>Everything the stream needs to go on, as bytes: <see cref="Model.Restore"/>
        /// on the same model, in this process or another, continues it bit for bit.</summary>
        public byte[] Snapshot()
        {
            UIntPtr size;
            Native.Check(Native.troupe_session_snapshot(Live(), null, UIntPtr.Zero, out size));
            var bytes = new byte[(int)size];
            Native.Check(Native.troupe_session_snapshot(Live(), bytes, size, out size));
            return bytes;
        }

        /// <summary>The session's penetration guard (every streaming family; off with enabled
        /// false): each frame sent is shifted in the floor plane out of the input person's body,
        /// at most maxSpeed m/s.</summary>
        public void SetPenetrationGuard(bool enabled, float dSafe = 0.05f, float maxSpeed = 2.0f)
        {
            Native.Check(Native.troupe_session_set_penetration_guard(Live(), enabled ? 1 : 0, dSafe, maxSpeed));
        }

        /// <summary>The session's root smoothing (every streaming family; off with enabled false):
        /// the generated person's root path filtered with timeConstant seconds, before the
        /// guard.</summary>
        public void SetRootSmoothing(bool enabled, float timeConstant = 0.1f)
        {
            Native.Check(Native.troupe_session_set_root_smoothing(Live(), enabled ? 1 : 0, timeConstant));
        }

        /// <summary>The session's foot lock on the poses StepJoints returns (ARMFlow, ARFlow; off
        /// with enabled false): a foot whose ankle contact label is at least contactThreshold stays put, released
        /// over releaseFrames frames or when the motion is maxStretch metres away.</summary>
        public void SetFootLock(bool enabled, float contactThreshold = 0.5f, uint releaseFrames = 4, float maxStretch = 0.25f)
        {
            Native.Check(Native.troupe_session_set_foot_lock(Live(), enabled ? 1 : 0, contactThreshold, releaseFrames, maxStretch));
        }

        /// <summary>What only an ARMFlow stream takes (its recentring). Its calls on another
        /// family's stream throw UnsupportedException.</summary>
        public ArmflowSession Armflow { get { return new ArmflowSession(this); } }

        /// <summary>What only a MAGNet live partner takes (its opening frames, configuration and
        /// early emission). Its calls on another family's stream throw UnsupportedException.</summary>
        public MagnetSession Magnet { get { return new MagnetSession(this); } }

        /// <summary>Deprecated since 0.2: Session.Armflow.SetRecentring.</summary>
        [Obsolete("use Session.Armflow.SetRecentring")]
        public void SetRecentring(bool enabled, float distance = 1.0f)
        {
            Armflow.SetRecentring(enabled, distance);
        }

        internal SessionHandle Handle() { return Live(); }
        internal int FrameDim { get { return frameDim; } }

        /// <summary>Frees the session.</summary>
        public void Dispose()
        {
            disposed = true;
            handle.Dispose();
        }

        private static void CheckFrames(float[] data, string name, int frames, int floatsPerFrame)
        {
            if (data == null) throw new ArgumentNullException(name);
            if (frames < 0 || (long)frames * floatsPerFrame > data.Length)
                throw new ArgumentException(name + " holds " + data.Length + " floats, fewer than " + frames
                    + " frames of " + floatsPerFrame, name);
        }
    }

    /// <summary>
    /// Plays poses a session produces at its frame rate on an engine's clock, which ticks at its
    /// own rate (20, 60, 144 frames a second, or unevenly): each <see cref="Sample"/> moves the
    /// playhead by the engine's elapsed time and gives the pose there, interpolated between the
    /// two poses around it. Poses arrive a token (several frames) at a time; the playhead trails
    /// the newest pose so that it plays smoothly between arrivals, and when it falls further
    /// behind than <c>maxBehindFrames</c> (a slow engine frame, a hitch) it jumps ahead, so the
    /// poses held stay bounded whatever the engine's rate. Before the first pose, and when it
    /// catches up with the newest, it holds the last pose. Not thread-safe: one engine thread.
    /// </summary>
    public sealed class PosePlayback
    {
        private readonly int floatsPerPose;
        private readonly float rate;
        private readonly float maxBehind;
        private readonly List<float[]> poses = new List<float[]>();
        // The index (in frames since the first pose) of poses[0], and the playhead.
        private long first;
        private double playhead;

        /// <summary>Poses of <paramref name="floatsPerPose"/> floats each (66 for t2m-22 joint
        /// positions) produced at <paramref name="rate"/> frames a second; the playhead is never
        /// more than <paramref name="maxBehindFrames"/> frames behind the newest pose.</summary>
        public PosePlayback(int floatsPerPose, float rate, float maxBehindFrames = 8f)
        {
            if (floatsPerPose <= 0) throw new ArgumentOutOfRangeException("floatsPerPose");
            if (!(rate > 0f) || float.IsInfinity(rate)) throw new ArgumentOutOfRangeException("rate");
            if (!(maxBehindFrames >= 1f) || float.IsInfinity(maxBehindFrames))
                throw new ArgumentOutOfRangeException("maxBehindFrames");
            this.floatsPerPose = floatsPerPose;
            this.rate = rate;
            maxBehind = maxBehindFrames;
        }

        /// <summary>The poses held (those the playhead has not passed), at most
        /// <c>maxBehindFrames + 2</c> after a <see cref="Sample"/>.</summary>
        public int Queued { get { return poses.Count; } }

        /// <summary>The playhead, in frames since the first pose pushed.</summary>
        public double Playhead { get { return playhead; } }

        /// <summary>How far the playhead trails the newest pose, in frames.</summary>
        public double BehindFrames { get { return poses.Count == 0 ? 0 : first + poses.Count - 1 - playhead; } }

        /// <summary>Appends <paramref name="count"/> poses, stored one after another in
        /// <paramref name="data"/> (what <see cref="Session.StepJoints"/> wrote).</summary>
        public void Push(float[] data, int count)
        {
            if (data == null) throw new ArgumentNullException("data");
            if (count < 0 || (long)count * floatsPerPose > data.Length)
                throw new ArgumentException("data holds fewer than " + count + " poses", "data");
            for (int i = 0; i < count; i++)
            {
                var pose = new float[floatsPerPose];
                Array.Copy(data, i * floatsPerPose, pose, 0, floatsPerPose);
                poses.Add(pose);
            }
        }

        /// <summary>Moves the playhead by <paramref name="deltaSeconds"/> and writes the pose
        /// there into <paramref name="pose"/>; false (and nothing written) before the first
        /// pose.</summary>
        public bool Sample(float deltaSeconds, float[] pose)
        {
            if (pose == null) throw new ArgumentNullException("pose");
            if (pose.Length < floatsPerPose) throw new ArgumentException("pose holds fewer than " + floatsPerPose + " floats", "pose");
            if (!(deltaSeconds >= 0f) || float.IsInfinity(deltaSeconds)) throw new ArgumentOutOfRangeException("deltaSeconds");
            if (poses.Count == 0) return false;
            long newest = first + poses.Count - 1;
            playhead = Math.Min(playhead + deltaSeconds * (double)rate, newest);
            if (newest - playhead > maxBehind) playhead = newest - maxBehind;
            // Drop the poses the playhead has passed; keep the one it stands on.
            int passed = (int)Math.Min(Math.Floor(playhead) - first, poses.Count - 1);
            if (passed > 0)
            {
                poses.RemoveRange(0, passed);
                first += passed;
            }
            float[] a = poses[0];
            float[] b = poses.Count > 1 ? poses[1] : a;
            float t = (float)(playhead - first);
            for (int k = 0; k < floatsPerPose; k++) pose[k] = a[k] + (b[k] - a[k]) * t;
            return true;
        }
    }

    /// <summary>One person's take read from a BVH or FBX file as t2m-22 joint positions.</summary>
    public sealed class Take
    {
        /// <summary>Positions, frames * 22 * 3 floats, in <see cref="Format"/>.</summary>
        public float[] Positions;
        /// <summary>Frames in the take.</summary>
        public int Frames;
        /// <summary>How the positions are measured (the file's units, Y up, its frame rate).</summary>
        public JointsFormat Format;
        /// <summary>The t2m-22 joints the rig lacks and how they were placed, one line each.</summary>
        public string[] Inferred;
        /// <summary>For each t2m-22 joint, the rig joint it is read from (null where placed).</summary>
        public string[] Mapping;

        /// <summary>Reads a BVH or FBX file (told apart by content). <paramref name="units"/>:
        /// the file's, or null to guess (an FBX file declares its own and is converted to
        /// <paramref name="units"/>, metres for null); <paramref name="jointMapJson"/>: null for
        /// the built-in names.</summary>
        public static Take Read(string path, Units? units = null, string jointMapJson = null)
        {
            if (path == null) throw new ArgumentNullException("path");
            Native.CheckAbi();
            IntPtr h;
            Native.Check(Native.troupe_bvh_read(Native.Utf8Z(path), jointMapJson == null ? null : Native.Utf8Z(jointMapJson),
                units.HasValue ? (uint)units.Value : Native.UnitsAuto, out h));
            try
            {
                var take = new Take { Frames = (int)Native.troupe_bvh_frames(h) };
                take.Positions = new float[take.Frames * Native.Joints * 3];
                Native.Check(Native.troupe_bvh_positions(h, take.Positions, (UIntPtr)take.Positions.Length));
                var c = new Native.JointsFormatC();
                Native.Check(Native.troupe_bvh_format(h, ref c, (UIntPtr)Marshal.SizeOf(typeof(Native.JointsFormatC))));
                take.Format = JointsFormat.FromC(c);
                string said = Native.Utf8(Native.troupe_bvh_inferred(h)) ?? "";
                take.Inferred = said.Length == 0 ? new string[0] : said.Split('\n');
                take.Mapping = new string[Native.Joints];
                for (int k = 0; k < Native.Joints; k++) take.Mapping[k] = Native.Utf8(Native.troupe_bvh_joint_source(h, (UIntPtr)k));
                return take;
            }
            finally
            {
                Native.troupe_bvh_free(h);
            }
        }
    }

    /// <summary>Flags of retargeting (troupe's TROUPE_RETARGET_*).</summary>
    [Flags]
    public enum RetargetFlags : uint { None = 0, NoFootLock = 1, NoLimbIk = 2 }

    /// <summary>A character rig with its joint map (docs/RIGS.md): what motion is retargeted
    /// onto and written on. Immutable: any thread may use it.</summary>
    public sealed class Rig : IDisposable
    {
        internal readonly RigHandle Handle;
        private Rig(RigHandle handle) { Handle = handle; }

        /// <summary>The rig of a BVH or FBX file (its bind pose, or the frame
        /// <paramref name="restFrame"/> of a BVH file, as the rest pose).</summary>
        public static Rig FromFile(string path, Units? units = null, int? restFrame = null, string jointMapJson = null)
        {
            if (path == null) throw new ArgumentNullException("path");
            if (restFrame.HasValue && restFrame.Value < 0) throw new ArgumentOutOfRangeException("restFrame");
            Native.CheckAbi();
            RigHandle h;
            Native.Check(Native.troupe_rig_from_bvh(Native.Utf8Z(path), units.HasValue ? (uint)units.Value : Native.UnitsAuto,
                restFrame.HasValue ? (uint)restFrame.Value : Native.RigZeroPose,
                jointMapJson == null ? null : Native.Utf8Z(jointMapJson), out h));
            return new Rig(h);
        }

        /// <summary>The rig of skin <paramref name="skin"/> of a glTF file (.glb or .gltf).</summary>
        public static Rig FromGltf(string path, int skin = 0, string jointMapJson = null)
        {
            if (path == null) throw new ArgumentNullException("path");
            if (skin < 0) throw new ArgumentOutOfRangeException("skin");
            Native.CheckAbi();
            RigHandle h;
            Native.Check(Native.troupe_rig_from_gltf(Native.Utf8Z(path), (UIntPtr)skin,
                jointMapJson == null ? null : Native.Utf8Z(jointMapJson), out h));
            return new Rig(h);
        }

        /// <summary>A rig from its JSON document (an engine's skeleton: Unity's Humanoid bones
        /// with "handedness": "left").</summary>
        public static Rig FromJson(string json, string jointMapJson = null)
        {
            if (json == null) throw new ArgumentNullException("json");
            Native.CheckAbi();
            RigHandle h;
            Native.Check(Native.troupe_rig_from_json(Native.Utf8Z(json), jointMapJson == null ? null : Native.Utf8Z(jointMapJson), out h));
            return new Rig(h);
        }

        /// <summary>Joints of the rig.</summary>
        public int JointCount { get { return (int)Native.troupe_rig_joint_count(Handle); } }
        /// <summary>Joint <paramref name="joint"/>'s name (null past the end).</summary>
        public string JointName(int joint)
        {
            return joint < 0 ? null : Native.Utf8(Native.troupe_rig_joint_name(Handle, (UIntPtr)joint));
        }

        /// <summary>One person's clip (frames * 22 * 3 floats, as <paramref name="format"/>
        /// says) retargeted onto the rig and written as a BVH file of its hierarchy.</summary>
        public void WriteBvh(string path, float[] positions, int frames, JointsFormat format,
                             Units units = Units.Centimetres, RetargetFlags flags = RetargetFlags.None)
        {
            Write(path, positions, frames, format, units, flags, false);
        }

        /// <summary>The same as a binary FBX file of the rig's skeleton (Blender, Unity, Unreal,
        /// Maya import it).</summary>
        public void WriteFbx(string path, float[] positions, int frames, JointsFormat format,
                             Units units = Units.Centimetres, RetargetFlags flags = RetargetFlags.None)
        {
            Write(path, positions, frames, format, units, flags, true);
        }

        /// <summary>People (people * frames * 22 * 3 floats) retargeted onto the rig as one glTF
        /// binary file, a skinned body each; <paramref name="names"/> names them.</summary>
        public void WriteGltf(string path, string[] names, float[] positions, int frames, JointsFormat format,
                              RetargetFlags flags = RetargetFlags.None)
        {
            if (path == null) throw new ArgumentNullException("path");
            if (names == null) throw new ArgumentNullException("names");
            Check(positions, frames * names.Length);
            var c = format.ToC();
            var utf8 = new IntPtr[names.Length];
            try
            {
                for (int i = 0; i < names.Length; i++)
                {
                    if (names[i] == null) continue;
                    byte[] bytes = Native.Utf8Z(names[i]);
                    utf8[i] = Marshal.AllocHGlobal(bytes.Length);
                    Marshal.Copy(bytes, 0, utf8[i], bytes.Length);
                }
                Native.Check(Native.troupe_gltf_write(Native.Utf8Z(path), Handle, positions, (UIntPtr)names.Length,
                    (UIntPtr)frames, ref c, utf8, (uint)flags));
            }
            finally
            {
                foreach (IntPtr p in utf8) if (p != IntPtr.Zero) Marshal.FreeHGlobal(p);
            }
        }

        private void Write(string path, float[] positions, int frames, JointsFormat format, Units units,
                           RetargetFlags flags, bool fbx)
        {
            if (path == null) throw new ArgumentNullException("path");
            Check(positions, frames);
            var c = format.ToC();
            int status = fbx
                ? Native.troupe_rig_fbx_write(Native.Utf8Z(path), Handle, positions, (UIntPtr)frames, ref c, (uint)units, (uint)flags)
                : Native.troupe_rig_bvh_write(Native.Utf8Z(path), Handle, positions, (UIntPtr)frames, ref c, (uint)units, (uint)flags);
            Native.Check(status);
        }

        private static void Check(float[] positions, int frames)
        {
            if (positions == null) throw new ArgumentNullException("positions");
            if (frames < 1 || (long)frames * Native.Joints * 3 > positions.Length)
                throw new ArgumentException("positions holds fewer than " + frames + " frames of 22 joints", "positions");
        }

        /// <summary>Frees the rig (retargeters made from it keep their own copy).</summary>
        public void Dispose() { Handle.Dispose(); }
    }

    /// <summary>One stream of t2m-22 positions retargeted onto a rig a frame at a time, with
    /// no latency. One thread at a time.</summary>
    public sealed class Retargeter : IDisposable
    {
        private readonly RetargeterHandle handle;
        private readonly int joints;

        /// <summary>A retargeter onto <paramref name="rig"/> of positions measured as
        /// <paramref name="format"/> says.</summary>
        public Retargeter(Rig rig, JointsFormat format, RetargetFlags flags = RetargetFlags.None)
        {
            if (rig == null) throw new ArgumentNullException("rig");
            var c = format.ToC();
            Native.Check(Native.troupe_rig_retargeter_new(rig.Handle, ref c, (uint)flags, out handle));
            joints = rig.JointCount;
        }

        /// <summary>The rig's pose for the next frame (22 * 3 floats): each joint's local
        /// rotation (w x y z, joints * 4 floats, in the rig's axes) into
        /// <paramref name="rotations"/>, the moving joint's translation into
        /// <paramref name="rootTranslation"/> (3 floats); returns the moving joint.</summary>
        public int Push(float[] frame, float[] rotations, float[] rootTranslation)
        {
            if (frame == null) throw new ArgumentNullException("frame");
            if (rotations == null) throw new ArgumentNullException("rotations");
            if (rootTranslation == null) throw new ArgumentNullException("rootTranslation");
            if (frame.Length < Native.Joints * 3) throw new ArgumentException("frame holds fewer than 66 floats", "frame");
            if (rotations.Length < joints * 4) throw new ArgumentException("rotations holds fewer than " + joints * 4 + " floats", "rotations");
            if (rootTranslation.Length < 3) throw new ArgumentException("rootTranslation holds fewer than 3 floats", "rootTranslation");
            UIntPtr root;
            Native.Check(Native.troupe_rig_retarget_push(handle, frame, (UIntPtr)(Native.Joints * 3), rotations,
                (UIntPtr)(joints * 4), rootTranslation, out root));
            return (int)root;
        }

        /// <summary>For each t2m-22 joint, the rig joint it drives (-1: none).</summary>
        public long[] Mapping()
        {
            var out_ = new long[Native.Joints];
            Native.Check(Native.troupe_rig_retargeter_mapping(handle, out_, (UIntPtr)out_.Length));
            return out_;
        }

        /// <summary>Forgets the stream (foot contacts, smoothing).</summary>
        public void Reset() { Native.Check(Native.troupe_rig_retarget_reset(handle)); }

        /// <summary>Frees the retargeter.</summary>
        public void Dispose() { handle.Dispose(); }
    }

    /// <summary>A rig handle, freed once with troupe_rig_free.</summary>
    public sealed class RigHandle : SafeHandle
    {
        /// <summary>An empty handle (the marshaller fills it).</summary>
        public RigHandle() : base(IntPtr.Zero, true) { }
        /// <summary>Whether the handle holds no rig.</summary>
        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }
        /// <summary>Frees the rig.</summary>
        protected override bool ReleaseHandle() { Native.troupe_rig_free(handle); return true; }
    }

    /// <summary>A retargeter handle, freed once with troupe_rig_retargeter_free.</summary>
    public sealed class RetargeterHandle : SafeHandle
    {
        /// <summary>An empty handle (the marshaller fills it).</summary>
        public RetargeterHandle() : base(IntPtr.Zero, true) { }
        /// <summary>Whether the handle holds no retargeter.</summary>
        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }
        /// <summary>Frees the retargeter.</summary>
        protected override bool ReleaseHandle() { Native.troupe_rig_retargeter_free(handle); return true; }
    }

    /// <summary>A model handle, freed once with troupe_model_free.</summary>
    public sealed class ModelHandle : SafeHandle
    {
        /// <summary>An empty handle (the marshaller fills it).</summary>
        public ModelHandle() : base(IntPtr.Zero, true) { }
        /// <summary>Whether the handle holds no model.</summary>
        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }
        /// <summary>Frees the model.</summary>
        protected override bool ReleaseHandle() { Native.troupe_model_free(handle); return true; }
    }

    /// <summary>A session handle, freed once with troupe_session_free. It holds a reference to
    /// its model's handle, so the model handle stays valid (for condition lookups) until the
    /// session is freed, whenever the Model is disposed.</summary>
    public sealed class SessionHandle : SafeHandle
    {
        private ModelHandle model;

        /// <summary>An empty handle (the marshaller fills it).</summary>
        public SessionHandle() : base(IntPtr.Zero, true) { }
        /// <summary>Whether the handle holds no session.</summary>
        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }

        internal void HoldModel(ModelHandle owner)
        {
            bool added = false;
            owner.DangerousAddRef(ref added);
            if (added) model = owner;
        }

        internal IntPtr Model { get { return model.DangerousGetHandle(); } }

        /// <summary>Frees the session, then lets go of the model.</summary>
        protected override bool ReleaseHandle()
        {
            Native.troupe_session_free(handle);
            if (model != null) model.DangerousRelease();
            return true;
        }
    }

    /// <summary>The C functions, as include/troupe.h declares them.</summary>
    internal static class Native
    {
        private const string Lib = "troupe";
        internal const int Joints = 22;
        internal const uint AbiVersion = 1;

        [StructLayout(LayoutKind.Sequential)]
        internal struct SessionOptionsC
        {
            public uint struct_size;
            public uint steps;
            public ulong seed;
            public float cfg_scale;
            public uint context_capacity;
            public int actor_latent;
            public uint reserved;
        }

        [StructLayout(LayoutKind.Sequential)]
        internal struct JointsFormatC
        {
            public uint struct_size;
            public uint units;
            public uint up_axis;
            public uint handedness;
            public float fps;
            public uint reserved;
        }

        [StructLayout(LayoutKind.Sequential)]
        internal struct PoseBuffersC
        {
            public IntPtr positions;
            public UIntPtr positions_len;
            public IntPtr rotations;
            public UIntPtr rotations_len;
            public IntPtr rotations_6d;
            public UIntPtr rotations_6d_len;
            public IntPtr contacts;
            public UIntPtr contacts_len;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_version_string();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern uint troupe_abi_version();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_status_name(int status);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_last_error_message();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_model_load_file(byte[] path, out ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_model_load_memory(byte[] data, UIntPtr len, out ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_model_free(IntPtr model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_frame_dim(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_fps(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_frames_per_token(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_condition_dim(IntPtr model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_condition_label_count(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_model_condition_label(ModelHandle model, UIntPtr index);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_model_condition_for_label(IntPtr model, byte[] label, [Out] float[] condition, UIntPtr capacity);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_options_init(ModelHandle model, ref SessionOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_new(ModelHandle model, ref SessionOptionsC options, out SessionHandle session);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_session_free(IntPtr session);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_step(SessionHandle session, [In] float[] actor, UIntPtr frames, [Out] float[] output, UIntPtr capacity, out UIntPtr written);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_reset(SessionHandle session);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_snapshot(SessionHandle session, byte[] buf, UIntPtr capacity, out UIntPtr needed);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_restore(ModelHandle model, byte[] bytes, UIntPtr len, out SessionHandle session);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_model_identity(ModelHandle model, byte[] id);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_penetration_guard(SessionHandle session, int enabled, float dSafe, float maxSpeed);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_root_smoothing(SessionHandle session, int enabled, float timeConstant);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_session_set_recentring(SessionHandle session, int enabled, float distance);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_session_set_partner_opening(SessionHandle session, float[] frames, UIntPtr nFrames);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_session_set_early_emission(SessionHandle session, int early);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_session_set_live_config(SessionHandle session, byte[] config);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_model_family(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_foot_lock(SessionHandle session, int enabled, float contactThreshold, uint releaseFrames, float maxStretch);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_seed(SessionHandle session, ulong seed);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_condition(SessionHandle session, [In] float[] condition, UIntPtr len);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_joints_format_init(ref JointsFormatC format, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_joints_format(SessionHandle session, ref JointsFormatC format);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_joints_ready_after(SessionHandle session, UIntPtr frames, out UIntPtr ready);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_step_joints(SessionHandle session, [In] float[] actor, UIntPtr frames, ref PoseBuffersC output, UIntPtr capacity, out UIntPtr written);

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern uint troupe_version_number();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_compute_threads();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_set_compute_threads(UIntPtr threads);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_load_threads();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_set_load_threads(UIntPtr threads);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_latency_frames(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_joints_latency_frames(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_latent_dim(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_clip_frames(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_takes_prompts(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_snapshot_seal(byte[] snapshot, UIntPtr len, byte[] key, UIntPtr keyLen, byte[] buf, UIntPtr capacity, out UIntPtr needed);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_restore_sealed(ModelHandle model, byte[] bytes, UIntPtr len, byte[] key, UIntPtr keyLen, out SessionHandle session);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_steps(SessionHandle session, uint steps);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_cfg_scale(SessionHandle session, float scale);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_set_prompt(SessionHandle session, byte[] prompt);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_output_frames(SessionHandle session, UIntPtr frames, out UIntPtr n);
        [StructLayout(LayoutKind.Sequential)]
        internal struct ArflowOptionsC
        {
            public uint struct_size;
            public uint steps;
            public float guidance;
            public float weight;
            public float eta;
            public float d_safe;
            public float sigma;
            public uint flags;
            public ulong seed;
        }

        [StructLayout(LayoutKind.Sequential)]
        internal struct ClipOptionsC
        {
            public uint struct_size;
            public uint steps;
            public ulong seed;
            public float cfg_scale;
            public uint reserved;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_arflow_options_init(ModelHandle model, ref ArflowOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_arflow_generate(ModelHandle model, ref ArflowOptionsC options, [In] float[] actor, UIntPtr frames, [Out] float[] output, UIntPtr capacityFrames);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_clip_options_init(ModelHandle model, ref ClipOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_clip_generate_with_options(ModelHandle model, ref ClipOptionsC options, [In] float[] actor, UIntPtr frames, [In] float[] condition, UIntPtr conditionLen, IntPtr noise, [Out] float[] output, UIntPtr capacity, [Out] float[] latents, UIntPtr latentsCapacity);
        internal const uint UnitsAuto = 0xFFFFFFFF;
        internal const uint RigZeroPose = 0xFFFFFFFF;
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_bvh_read(byte[] path, byte[] jointMapJson, uint units, out IntPtr bvh);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_bvh_frames(IntPtr bvh);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_bvh_format(IntPtr bvh, ref JointsFormatC format, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_bvh_positions(IntPtr bvh, [Out] float[] positions, UIntPtr len);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_bvh_inferred(IntPtr bvh);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_bvh_joint_source(IntPtr bvh, UIntPtr joint);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_bvh_free(IntPtr bvh);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_from_bvh(byte[] path, uint units, uint restFrame, byte[] jointMapJson, out RigHandle rig);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_from_gltf(byte[] path, UIntPtr skin, byte[] jointMapJson, out RigHandle rig);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_from_json(byte[] json, byte[] jointMapJson, out RigHandle rig);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_rig_free(IntPtr rig);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_rig_joint_count(RigHandle rig);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_rig_joint_name(RigHandle rig, UIntPtr joint);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_retargeter_new(RigHandle rig, ref JointsFormatC format, uint flags, out RetargeterHandle retargeter);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_retarget_push(RetargeterHandle retargeter, [In] float[] positions, UIntPtr len, [Out] float[] rotations, UIntPtr rotationsLen, [Out] float[] rootTranslation, out UIntPtr rootJoint);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_retarget_reset(RetargeterHandle retargeter);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_retargeter_mapping(RetargeterHandle retargeter, [Out] long[] rigJoints, UIntPtr capacity);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_rig_retargeter_free(IntPtr retargeter);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_gltf_write(byte[] path, RigHandle rig, [In] float[] positions, UIntPtr people, UIntPtr frames, ref JointsFormatC format, IntPtr[] names, uint flags);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_bvh_write(byte[] path, RigHandle rig, [In] float[] positions, UIntPtr frames, ref JointsFormatC format, uint units, uint flags);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_fbx_write(byte[] path, RigHandle rig, [In] float[] positions, UIntPtr frames, ref JointsFormatC format, uint units, uint flags);

        private static bool abiChecked;

        /// <summary>Refuses a library of another ABI before any other call.</summary>
        internal static void CheckAbi()
        {
            if (abiChecked) return;
            uint abi = troupe_abi_version();
            if (abi != AbiVersion)
                throw new TroupeException(-1, "TROUPE_ERR_UNKNOWN", "the native library speaks troupe ABI " + abi
                    + ", this binding needs " + AbiVersion);
            abiChecked = true;
        }

        internal static void Check(int status)
        {
            if (status != 0) throw TroupeException.FromStatus(status, Utf8(troupe_last_error_message()) ?? "");
        }

        /// <summary>A NUL-terminated UTF-8 copy of <paramref name="s"/>; a NUL inside it is refused.</summary>
        internal static byte[] Utf8Z(string s)
        {
            if (s.IndexOf('\0') >= 0) throw new ArgumentException("a string passed to troupe cannot hold NUL characters");
            var bytes = new byte[Encoding.UTF8.GetByteCount(s) + 1];
            Encoding.UTF8.GetBytes(s, 0, s.Length, bytes, 0);
            return bytes;
        }

        /// <summary>The NUL-terminated UTF-8 string at <paramref name="p"/> (null for NULL).</summary>
        internal static string Utf8(IntPtr p)
        {
            if (p == IntPtr.Zero) return null;
            int n = 0;
            while (Marshal.ReadByte(p, n) != 0) n++;
            var bytes = new byte[n];
            Marshal.Copy(p, bytes, 0, n);
            return Encoding.UTF8.GetString(bytes);
        }
    }
}
