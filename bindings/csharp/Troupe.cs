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
// to the library pinned, never copied. Native code calls back into managed code only where the
// caller asks it to: Library.SetLogCallback (any thread) and Library.SetProgressCallback (the
// calling thread). Both go through static trampolines marked [MonoPInvokeCallback] (what Unity's
// IL2CPP needs), whose delegates live in static fields for the life of the process, and which
// never let a managed exception unwind into native code (a progress callback that throws cancels
// the call; the CancelledException carries the exception as its InnerException).
//
// Ownership and threading follow the C ABI: a Model may be shared by any number of threads and
// sessions keep it alive; a Session (and a MotionStream) is used by one thread at a time (a
// second thread gets BusyException). Model, Session, Rig, Retargeter and MotionStream own their
// native handles through SafeHandles: Dispose them (or let the finalizer) and they are freed
// once. The C structs of options are mirrored here and passed with their size (struct_size):
// a newer library reads them as the version they are, and before first use each mirror is
// checked against the library's own size (troupe_*_options_size), so an older library, which
// lacks fields this binding fills, is refused with a TroupeException instead of misreading
// them. Every failed call throws the TroupeException subclass of its status code with the library's message; a failed step leaves the session as
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

        /// <summary>An exception for <paramref name="status"/> caused by <paramref name="inner"/>
        /// (a progress callback that threw).</summary>
        internal TroupeException(int status, string name, string message, Exception inner)
            : base(name + ": " + message, inner)
        {
            Status = status;
            StatusName = name;
        }

        /// <summary>The exception class of a status code (a code this binding does not know,
        /// from a newer library, is a plain TroupeException carrying it); <paramref name="inner"/>
        /// is what a progress callback threw before it cancelled the call.</summary>
        internal static TroupeException FromStatus(int status, string message, Exception inner = null)
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
                case 11: return new CancelledException(status, name, message, inner);
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
    public sealed class CancelledException : TroupeException { internal CancelledException(int s, string n, string m, Exception inner) : base(s, n, m, inner) { } }
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
    public enum Units : uint
    {
        /// <summary>Metres.</summary>
        Metres = 0,
        /// <summary>Centimetres.</summary>
        Centimetres = 1,
        /// <summary>Millimetres.</summary>
        Millimetres = 2,
        /// <summary>Inches.</summary>
        Inches = 3,
    }
    /// <summary>The up axis of joint positions.</summary>
    public enum UpAxis : uint
    {
        /// <summary>+Y is up (troupe, Unity, glTF, most BVH).</summary>
        Y = 0,
        /// <summary>+Z is up (SMPL data, Blender, Unreal).</summary>
        Z = 1,
    }
    /// <summary>Handedness of the caller's axes.</summary>
    public enum Handedness : uint
    {
        /// <summary>Right-handed axes.</summary>
        Right = 0,
        /// <summary>Left-handed axes (Unity, Unreal).</summary>
        Left = 1,
    }

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
        /// <summary>Penetration guidance's scale λ (0: none).</summary>
        public float? Guidance;
        /// <summary>The reweighting toward the actor w, in [0, 1] (1: none).</summary>
        public float? Weight;
        /// <summary>The stochastic share η, in [0, 1) (0: deterministic).</summary>
        public float? Eta;
        /// <summary>The penetration loss's safe distance, metres, in [0, 1].</summary>
        public float? DSafe;
        /// <summary>The start noise σ (0: the flow starts at the actor exactly).</summary>
        public float? Sigma;
        /// <summary>The sampler's flags (null: the bundle's).</summary>
        public ArflowFlags? Flags;

        internal static Native.ArflowOptionsC ToC(ModelHandle model, ArflowOptions options)
        {
            var c = new Native.ArflowOptionsC();
            Native.Check(Native.troupe_arflow_options_init(model, ref c, Native.ArflowOptionsSize()));
            return Apply(c, options);
        }

        internal static Native.ArflowOptionsC ToC(IntPtr model, ArflowOptions options)
        {
            var c = new Native.ArflowOptionsC();
            Native.Check(Native.troupe_arflow_options_init(model, ref c, Native.ArflowOptionsSize()));
            return Apply(c, options);
        }

        private static Native.ArflowOptionsC Apply(Native.ArflowOptionsC c, ArflowOptions o)
        {
            if (o == null) return c;
            c.seed = o.Seed;
            if (o.Steps.HasValue) c.steps = o.Steps.Value;
            if (o.Guidance.HasValue) c.guidance = o.Guidance.Value;
            if (o.Weight.HasValue) c.weight = o.Weight.Value;
            if (o.Eta.HasValue) c.eta = o.Eta.Value;
            if (o.DSafe.HasValue) c.d_safe = o.DSafe.Value;
            if (o.Sigma.HasValue) c.sigma = o.Sigma.Value;
            if (o.Flags.HasValue) c.flags = (uint)o.Flags.Value;
            return c;
        }
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
            var opt = SessionOptionsC(options);
            SessionHandle session;
            Native.Check(Native.troupe_session_new(h, ref opt, out session));
            session.HoldModel(h);
            return new Session(session, FrameDim);
        }

        /// <summary>The bundle's session options with <paramref name="options"/>' fields over them.</summary>
        internal Native.SessionOptionsC SessionOptionsC(SessionOptions options)
        {
            var opt = new Native.SessionOptionsC();
            Native.Check(Native.troupe_session_options_init(Live(), ref opt, Native.SessionOptionsSize()));
            if (options != null)
            {
                opt.seed = options.Seed;
                if (options.Steps.HasValue) opt.steps = options.Steps.Value;
                if (options.CfgScale.HasValue) opt.cfg_scale = options.CfgScale.Value;
                if (options.ContextCapacity.HasValue) opt.context_capacity = options.ContextCapacity.Value;
            }
            return opt;
        }

        /// <summary>What only an ARMFlow model offers (its clip, its own session options).</summary>
        public ArmflowModel Armflow { get { return new ArmflowModel(this); } }
        /// <summary>What only a UMF model offers (groups from text).</summary>
        public UmfModel Umf { get { return new UmfModel(this); } }
        /// <summary>What only a MAGNet model offers (the released tasks).</summary>
        public MagnetModel Magnet { get { return new MagnetModel(this); } }
        /// <summary>What only an ARFlow model offers (whole reactions, given draws).</summary>
        public ArflowModel Arflow { get { return new ArflowModel(this); } }

        /// <summary>Floats of a conditioning vector (Session.SetCondition, UMF groups, prompts).</summary>
        public int ConditionDim { get { return (int)Native.troupe_model_condition_dim(Live()); } }

        /// <summary>The graphs whose weights are not float32, as (role, storage) pairs
        /// (("velocity", "int8")); empty for a float32 bundle.</summary>
        public IList<KeyValuePair<string, string>> ReducedPrecision
        {
            get
            {
                var h = Live();
                var graphs = new List<KeyValuePair<string, string>>();
                ulong n = (ulong)Native.troupe_model_reduced_precision_count(h);
                for (ulong i = 0; i < n; i++)
                    graphs.Add(new KeyValuePair<string, string>(Native.Utf8(Native.troupe_model_reduced_precision_graph(h, (UIntPtr)i)),
                        Native.Utf8(Native.troupe_model_reduced_precision_weights(h, (UIntPtr)i))));
                return graphs;
            }
        }

        /// <summary>The most frames one Session.Step of <paramref name="actorFrames"/> frames can
        /// return, whatever the session's state: size output arrays with it.</summary>
        public int MaxOutputFrames(int actorFrames)
        {
            if (actorFrames < 0) throw new ArgumentOutOfRangeException("actorFrames");
            return (int)Native.troupe_model_max_output_frames(Live(), (UIntPtr)actorFrames);
        }

        /// <summary>Width of the CLIP token features EncodeText reads (0: no text branch).</summary>
        public int TextTokenDim { get { return (int)Native.troupe_model_text_token_dim(Live()); } }

        /// <summary>The condition of a text prompt (ConditionDim floats): CLIP's tokenizer and
        /// text tower, then the bundle's text branch; "" is the official "no text". A model
        /// without TakesPrompts throws InvalidArgumentException.</summary>
        public float[] EncodePrompt(string prompt)
        {
            if (prompt == null) throw new ArgumentNullException("prompt");
            var h = Live();
            var condition = new float[ConditionDim];
            Native.Check(Native.troupe_text_prompt_encode(h, Native.Utf8Z(prompt), condition, (UIntPtr)condition.Length));
            return condition;
        }

        /// <summary>The condition of CLIP token features computed elsewhere:
        /// <paramref name="tokens"/> holds <paramref name="count"/> rows of TextTokenDim floats
        /// (CLIP's final LayerNorm for one prompt), the end-of-text token at
        /// <paramref name="eotIndex"/>. A model without a text branch, or an index out of range,
        /// throws InvalidArgumentException.</summary>
        public float[] EncodeText(float[] tokens, int count, int eotIndex)
        {
            if (tokens == null) throw new ArgumentNullException("tokens");
            if (count < 0 || (long)count * TextTokenDim > tokens.Length)
                throw new ArgumentException("tokens holds fewer than " + count + " tokens of " + TextTokenDim + " floats", "tokens");
            if (eotIndex < 0) throw new ArgumentOutOfRangeException("eotIndex");
            var h = Live();
            var condition = new float[ConditionDim];
            Native.Check(Native.troupe_text_encode(h, tokens, (UIntPtr)count, (UIntPtr)eotIndex, condition, (UIntPtr)condition.Length));
            return condition;
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
            var c = ArflowOptions.ToC(h, options);
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
            Native.Check(Native.troupe_armflow_clip_options_init(h, ref c, Native.ClipOptionsSize()));
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

        /// <summary>Queues the noise of the next token the stream has not generated yet, to
        /// reproduce a run exactly: the actor posterior's standard normals and the reactor's
        /// start noise, Model.LatentDim floats each. Reset drops it.</summary>
        public void QueueNoise(float[] actorNoise, float[] reactorNoise)
        {
            if (actorNoise == null) throw new ArgumentNullException("actorNoise");
            if (reactorNoise == null) throw new ArgumentNullException("reactorNoise");
            if (actorNoise.Length != reactorNoise.Length)
                throw new ArgumentException("actorNoise and reactorNoise differ in length", "reactorNoise");
            Native.Check(Native.troupe_armflow_session_queue_noise(session.Handle(), actorNoise, reactorNoise, (UIntPtr)actorNoise.Length));
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

        /// <summary>What only an ARFlow online stream takes (its sampler settings). Its calls on
        /// another family's stream throw UnsupportedException.</summary>
        public ArflowSession Arflow { get { return new ArflowSession(this); } }

        /// <summary>What the stream takes beyond frames, seed and steps.</summary>
        public SessionCapabilities Capabilities
        {
            get
            {
                uint caps;
                Native.Check(Native.troupe_session_capabilities(Live(), out caps));
                return (SessionCapabilities)caps;
            }
        }

        /// <summary>Queues standard normals for the draws the stream makes next, in its
        /// sampler's order (docs: ARMFlow whole tokens of the actor's posterior noise then the
        /// reactor's start noise; MAGNet as docs/MAGNET.md gives; ARFlow per frame), to replay
        /// another implementation's stream exactly. A step whose draw needs more than are left
        /// throws InvalidArgumentException, the session as it was; Reset drops them.</summary>
        public void QueueNormals(float[] normals)
        {
            if (normals == null) throw new ArgumentNullException("normals");
            Native.Check(Native.troupe_session_queue_normals(Live(), normals, (UIntPtr)normals.Length));
        }

        /// <summary>Where StepJoints puts the poses (fixed by the first joint frame); before it,
        /// InvalidArgumentException.</summary>
        public Placement JointsPlacement()
        {
            Placement p;
            Native.Check(Native.troupe_session_joints_placement(Live(), out p));
            return p;
        }

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

        internal static void CheckFrames(float[] data, string name, int frames, int floatsPerFrame)
        {
            Motion.CheckFrames(data, name, frames, floatsPerFrame);
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
    public enum RetargetFlags : uint
    {
        /// <summary>No flag.</summary>
        None = 0,
        /// <summary>Do not pin feet in contact.</summary>
        NoFootLock = 1,
        /// <summary>No two-bone IK for hands and feet (feet are then not pinned either).</summary>
        NoLimbIk = 2,
        /// <summary>glTF files: no capsule bodies, the skeletons only.</summary>
        NoBodies = 4,
    }

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

        /// <summary>A whole clip (frames * 22 * 3 floats, as <paramref name="format"/> says)
        /// retargeted onto the rig, the source's proportions measured from the clip first (a
        /// Retargeter uses troupe's neutral body).</summary>
        public RigClip RetargetClip(float[] positions, int frames, JointsFormat format, RetargetFlags flags = RetargetFlags.None)
        {
            Check(positions, frames);
            var c = format.ToC();
            int joints = JointCount;
            var clip = new RigClip
            {
                Frames = frames,
                Joints = joints,
                Rotations = new float[(long)frames * joints * 4],
                RootTranslations = new float[frames * 3],
            };
            UIntPtr root;
            Native.Check(Native.troupe_rig_retarget_clip(Handle, positions, (UIntPtr)frames, ref c, (uint)flags, clip.Rotations,
                (UIntPtr)clip.Rotations.Length, clip.RootTranslations, (UIntPtr)clip.RootTranslations.Length, out root));
            clip.RootJoint = (int)root;
            return clip;
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

    /// <summary>Severity of a library log line (TROUPE_LOG_*).</summary>
    public enum LogLevel
    {
        /// <summary>Something failed.</summary>
        Error = 1,
        /// <summary>Something looks wrong.</summary>
        Warn = 2,
        /// <summary>Milestones (model loaded, session created).</summary>
        Info = 3,
        /// <summary>Details, including every error returned to the caller.</summary>
        Debug = 4,
    }

    /// <summary>troupe's limits (troupe_limits_get): a call given more than one fails, naming
    /// it, before anything is allocated (InvalidArgumentException for a caller's value,
    /// ModelException or IoException for a bundle's).</summary>
    public sealed class Limits
    {
        /// <summary>Bytes of a whole bundle (archive, memory, or a directory's files).</summary>
        public ulong MaxBundleBytes { get; internal set; }
        /// <summary>Bytes of troupe.json.</summary>
        public ulong MaxManifestBytes { get; internal set; }
        /// <summary>Members of a tar bundle.</summary>
        public ulong MaxArchiveMembers { get; internal set; }
        /// <summary>Nodes of one ONNX graph.</summary>
        public ulong MaxGraphNodes { get; internal set; }
        /// <summary>Elements of any one tensor.</summary>
        public ulong MaxTensorElements { get; internal set; }
        /// <summary>Solver steps per token or per stage.</summary>
        public ulong MaxSteps { get; internal set; }
        /// <summary>Magnitude of a classifier-free guidance scale.</summary>
        public ulong MaxCfgScale { get; internal set; }
        /// <summary>Magnitude of a motion feature or conditioning value passed in.</summary>
        public ulong MaxAbsInput { get; internal set; }
        /// <summary>Motion frames passed to one call.</summary>
        public ulong MaxFramesPerCall { get; internal set; }
        /// <summary>Tokens of noise queued on a session and not yet used.</summary>
        public ulong MaxQueuedNoiseTokens { get; internal set; }
        /// <summary>Tokens kept in a session's context cache.</summary>
        public ulong MaxContextCapacity { get; internal set; }
        /// <summary>People in one generated group.</summary>
        public ulong MaxPeople { get; internal set; }
        /// <summary>Text tokens passed to the text branch.</summary>
        public ulong MaxTextTokens { get; internal set; }
        /// <summary>Any integer a manifest declares.</summary>
        public ulong MaxManifestDim { get; internal set; }
        /// <summary>Bytes of UTF-8 in one text prompt.</summary>
        public ulong MaxPromptBytes { get; internal set; }
        /// <summary>Threads of the compute pool (Model.ComputeThreads).</summary>
        public ulong MaxComputeThreads { get; internal set; }
    }

    /// <summary>Process-wide and per-thread settings of the library: its limits, where its log
    /// goes, the calling thread's progress callback and call budget.</summary>
    public static class Library
    {
        /// <summary>troupe's limits, one set per build.</summary>
        public static Limits Limits
        {
            get
            {
                Native.CheckAbi();
                var c = new Native.LimitsC();
                Native.Check(Native.troupe_limits_get(ref c, (UIntPtr)Marshal.SizeOf(typeof(Native.LimitsC))));
                return new Limits
                {
                    MaxBundleBytes = c.max_bundle_bytes, MaxManifestBytes = c.max_manifest_bytes,
                    MaxArchiveMembers = c.max_archive_members, MaxGraphNodes = c.max_graph_nodes,
                    MaxTensorElements = c.max_tensor_elements, MaxSteps = c.max_steps, MaxCfgScale = c.max_cfg_scale,
                    MaxAbsInput = c.max_abs_input, MaxFramesPerCall = c.max_frames_per_call,
                    MaxQueuedNoiseTokens = c.max_queued_noise_tokens, MaxContextCapacity = c.max_context_capacity,
                    MaxPeople = c.max_people, MaxTextTokens = c.max_text_tokens, MaxManifestDim = c.max_manifest_dim,
                    MaxPromptBytes = c.max_prompt_bytes, MaxComputeThreads = c.max_compute_threads,
                };
            }
        }

        /// <summary>Checks every C struct this binding mirrors (session, ARMFlow session and clip,
        /// UMF, MAGNet and ARFlow options) against the library's size of it, throwing a
        /// TroupeException naming the first that differs: the native library is of another
        /// release than this Troupe.cs. Each mirror is also checked before its first use.</summary>
        public static void CheckStructSizes()
        {
            Native.SessionOptionsSize();
            Native.ClipOptionsSize();
            Native.ArmflowSessionOptionsSize();
            Native.GroupOptionsSize();
            Native.MagnetOptionsSize();
            Native.ArflowOptionsSize();
        }

        private static readonly object logLock = new object();
        private static volatile Action<LogLevel, string, string> log;
        // The delegates native code holds: static, so the GC never collects them.
        private static readonly Native.LogFn logThunk = OnLog;
        private static readonly Native.ProgressFn progressThunk = OnProgress;
        [ThreadStatic] private static Func<ulong, ulong, bool> progress;
        [ThreadStatic] private static Exception progressException;

        /// <summary>Sends the library's log lines at <paramref name="maxLevel"/> or more severe
        /// to <paramref name="callback"/>(level, target, message); null restores the default
        /// (silent, or stderr as the TROUPE_LOG environment variable says). Process-wide: the
        /// callback may be called from any thread that calls into troupe, at once, so it must be
        /// thread-safe, and it must not call troupe. What it throws is dropped. A level outside
        /// Error..Debug throws InvalidArgumentException and keeps the callback that was
        /// set.</summary>
        public static void SetLogCallback(Action<LogLevel, string, string> callback, LogLevel maxLevel = LogLevel.Warn)
        {
            Native.CheckAbi();
            lock (logLock)
            {
                var old = log;
                log = callback;
                int status = Native.troupe_set_log_callback(callback == null ? null : logThunk, IntPtr.Zero, (int)maxLevel);
                if (status != 0) log = old;
                Native.Check(status);
            }
        }

        /// <summary>Sets the calling thread's progress callback (null removes it): long calls this
        /// thread makes (Model.Load, group, clip, MAGNet and ARFlow generation, Take.Read,
        /// Motion.WriteViewer) report (done, total) to it between units of work, and stop with
        /// CancelledException when it returns false. A callback that throws cancels the call too;
        /// the CancelledException carries what it threw as its InnerException. To cancel from
        /// another thread, have the callback read a flag that thread sets.</summary>
        public static void SetProgressCallback(Func<ulong, ulong, bool> callback)
        {
            Native.CheckAbi();
            progress = callback;
            progressException = null;
            Native.troupe_set_progress_callback(callback == null ? null : progressThunk, IntPtr.Zero);
        }

        /// <summary>Bounds the long calls the calling thread makes (UMF groups, ARMFlow clips,
        /// MAGNet and ARFlow generation): one that would take more than
        /// <paramref name="maxWork"/> units of work (a group's network evaluations, a clip's
        /// tokens × steps, MAGNet's sampler iterations, ARFlow's sampler steps) is refused with
        /// InvalidArgumentException before it starts, and one that runs past
        /// <paramref name="maxSeconds"/> stops with CancelledException. 0 sets no bound; both 0
        /// remove the budget. A negative or NaN maxSeconds throws InvalidArgumentException and
        /// keeps the budget that was set.</summary>
        public static void SetCallBudget(ulong maxWork, double maxSeconds)
        {
            Native.CheckAbi();
            var c = new Native.CallBudgetC { max_work = maxWork, max_seconds = maxSeconds };
            Native.Check(Native.troupe_set_call_budget(ref c));
        }

        /// <summary>What the calling thread's progress callback threw before the call it
        /// cancelled failed (null if nothing), forgotten once taken.</summary>
        internal static Exception TakeProgressException()
        {
            Exception e = progressException;
            progressException = null;
            return e;
        }

        [AOT.MonoPInvokeCallback(typeof(Native.LogFn))]
        private static void OnLog(IntPtr userData, int level, IntPtr target, IntPtr message)
        {
            try
            {
                var f = log;
                if (f != null) f((LogLevel)level, Native.Utf8(target) ?? "", Native.Utf8(message) ?? "");
            }
            catch (Exception)
            {
                // Nothing may unwind into native code; a log line lost is all it costs.
            }
        }

        [AOT.MonoPInvokeCallback(typeof(Native.ProgressFn))]
        private static int OnProgress(IntPtr userData, ulong done, ulong total)
        {
            try
            {
                var f = progress;
                return f == null || f(done, total) ? 0 : 1;
            }
            catch (Exception e)
            {
                progressException = e;
                return 1;
            }
        }
    }

    /// <summary>What a stream takes beyond frames, seed and steps (TROUPE_CAP_*): a call for
    /// one it lacks throws UnsupportedException.</summary>
    [Flags]
    public enum SessionCapabilities : uint
    {
        /// <summary>Nothing beyond frames, seed and steps.</summary>
        None = 0,
        /// <summary>A conditioning vector (Session.SetCondition).</summary>
        Condition = 1,
        /// <summary>A text prompt (Session.SetPrompt).</summary>
        Prompt = 2,
        /// <summary>A CFG scale other than 1 (Session.SetCfgScale).</summary>
        CfgScale = 4,
        /// <summary>Queued standard normals (Session.QueueNormals).</summary>
        QueuedNormals = 8,
    }

    /// <summary>How an ARMFlow stream makes its actor tokens (TROUPE_ACTOR_LATENT_*).</summary>
    public enum ActorLatent
    {
        /// <summary>The VAE posterior sample (the official choice).</summary>
        Sample = 0,
        /// <summary>The posterior mean: no actor noise is drawn.</summary>
        Mean = 1,
    }

    /// <summary>Options only an ARMFlow stream takes (troupe_armflow_session_options); a field
    /// left null takes the bundle's default.</summary>
    public sealed class ArmflowSessionOptions
    {
        /// <summary>Classifier-free guidance scale (the stream guides only above 1).</summary>
        public float? CfgScale;
        /// <summary>How actor tokens are made.</summary>
        public ActorLatent? ActorLatent;
        /// <summary>Run the VAE over windows of frames (the reference path; slower, no recentring).</summary>
        public bool? VaeWindows;
    }

    /// <summary>An ODE solver of UMF (TROUPE_SOLVER_*).</summary>
    public enum Solver : uint
    {
        /// <summary>Forward Euler.</summary>
        Euler = 1,
        /// <summary>The 3/8-rule fourth-order Runge-Kutta (UMF's).</summary>
        Rk4 = 2,
    }

    /// <summary>Options of a UMF group (troupe_group_options); a field left null takes the
    /// bundle's default.</summary>
    public sealed class UmfOptions
    {
        /// <summary>Seed of the draws not given as UmfNoise.</summary>
        public ulong Seed;
        /// <summary>Classifier-free guidance scale (1: the conditional branch only).</summary>
        public float? CfgScale;
        /// <summary>Solver of each further person.</summary>
        public Solver? ReactionSolver;
        /// <summary>Intervals of the further persons' solve, at least 1.</summary>
        public uint? ReactionSteps;
        /// <summary>Solver of each pyramid stage, coarsest first (null: the bundle's; else one per stage).</summary>
        public Solver[] StageSolvers;
        /// <summary>Intervals of each pyramid stage (null: the bundle's; else one per stage).</summary>
        public uint[] StageSteps;
    }

    /// <summary>Every random draw of one UMF group, given instead of seeded (lengths from
    /// Model.Umf.NoiseLengths); row-major standard normals.</summary>
    public sealed class UmfNoise
    {
        /// <summary>The first person's start at the coarsest stage.</summary>
        public float[] Prior;
        /// <summary>The block noise of each jump, in stage order.</summary>
        public float[] Jumps;
        /// <summary>The noise half of each further person's start.</summary>
        public float[] Reactions;
    }

    /// <summary>Changes to a released MAGNet configuration for one generation
    /// (troupe_magnet_options); a field left null keeps the configuration's value.</summary>
    public sealed class MagnetOptions
    {
        /// <summary>Samples generated at once.</summary>
        public uint? Samples;
        /// <summary>DDIM steps.</summary>
        public uint? Steps;
        /// <summary>Frames to generate.</summary>
        public uint? SeqLen;
        /// <summary>Seed of troupe's generator instead of the configuration's.</summary>
        public ulong? Seed;
        /// <summary>DDIM η instead of the configuration's.</summary>
        public float? Eta;
        /// <summary>Turn the x0 corrections off: three to five times cheaper, not the released behaviour.</summary>
        public bool NoX0Guidance;
        /// <summary>In-betweening's key frames (at most 8; frames k..k + 4 set token k / 4), or null.</summary>
        public uint[] Keyframes;

        internal Native.MagnetOptionsC ToC()
        {
            var c = new Native.MagnetOptionsC { keyframes = new uint[Native.MaxKeyframes] };
            Native.Check(Native.troupe_magnet_options_init(ref c, Native.MagnetOptionsSize()));
            if (Samples.HasValue) c.samples = Samples.Value;
            if (Steps.HasValue) c.steps = Steps.Value;
            if (SeqLen.HasValue) c.seq_len = SeqLen.Value;
            if (Seed.HasValue) { c.seed = Seed.Value; c.flags |= 1; }
            if (Eta.HasValue) { c.eta = Eta.Value; c.flags |= 2; }
            if (NoX0Guidance) c.flags |= 4;
            if (Keyframes != null)
            {
                if (Keyframes.Length > Native.MaxKeyframes)
                    throw new ArgumentException("at most " + Native.MaxKeyframes + " key frames", "Keyframes");
                Array.Copy(Keyframes, c.keyframes, Keyframes.Length);
                c.keyframe_count = (uint)Keyframes.Length;
                c.flags |= 8;
            }
            return c;
        }

        internal static Native.MagnetOptionsC ToC(MagnetOptions options)
        {
            return (options ?? new MagnetOptions()).ToC();
        }
    }

    /// <summary>The shape of a MAGNet generation: [Samples][Frames][People][145] floats.</summary>
    public struct MagnetShape
    {
        /// <summary>Samples generated.</summary>
        public int Samples;
        /// <summary>Frames per sample.</summary>
        public int Frames;
        /// <summary>People per frame.</summary>
        public int People;
    }

    /// <summary>Flags of ARFlow's sampler (TROUPE_ARFLOW_*).</summary>
    [Flags]
    public enum ArflowFlags : uint
    {
        /// <summary>None: a linear hinge, guided back-projection, (1 − η) v + η ε.</summary>
        None = 0,
        /// <summary>A squared hinge in the penetration loss.</summary>
        SquaredHinge = 1,
        /// <summary>Back-project with the network's x̂_1, not the guided one.</summary>
        UnguidedBackprojection = 2,
        /// <summary>Mix the stochastic direction as √(1 − η²) v + η ε.</summary>
        VariancePreserving = 4,
    }

    /// <summary>Where a clip's canonical frame sits in the caller's world (mirror of
    /// <c>troupe_placement</c>): the floor height, the first frame's root x and z (metres, Y up)
    /// and the turn about +Y, a unit quaternion, that makes frame 0 face +Z. A plain value: pass
    /// it back to put motion where the caller's was, or a second person in the first one's
    /// frame.</summary>
    [StructLayout(LayoutKind.Sequential)]
    public struct Placement
    {
        /// <summary>Floor height, metres.</summary>
        public double Floor;
        /// <summary>First-frame root x, metres.</summary>
        public double OriginX;
        /// <summary>First-frame root z, metres.</summary>
        public double OriginZ;
        /// <summary>The turn's w.</summary>
        public double HeadingW;
        /// <summary>The turn's x.</summary>
        public double HeadingX;
        /// <summary>The turn's y.</summary>
        public double HeadingY;
        /// <summary>The turn's z.</summary>
        public double HeadingZ;
    }

    /// <summary>Poses in the caller's world: positions [Frames][22][3], rotations [Frames][22][4]
    /// (w x y z: joint 0 the root's world orientation, the others local to their parent), the
    /// same as 6-D vectors [Frames][22][6], and foot contacts [Frames][4] (left ankle, left foot,
    /// right ankle, right foot).</summary>
    public sealed class Poses
    {
        /// <summary>Frames of poses.</summary>
        public int Frames;
        /// <summary>Joint positions.</summary>
        public float[] Positions;
        /// <summary>Joint rotations as quaternions.</summary>
        public float[] Rotations;
        /// <summary>Joint rotations as 6-D vectors.</summary>
        public float[] Rotations6d;
        /// <summary>Foot contacts.</summary>
        public float[] Contacts;
    }

    /// <summary>How much two people's bodies pass through each other (docs/ARFLOW.md).</summary>
    public sealed class PenetrationMetrics
    {
        /// <summary>Frames where a joint lies inside the other body.</summary>
        public int FramesIntersecting;
        /// <summary>Their share of the frames (0 for none).</summary>
        public double Frequency;
        /// <summary>The depths of every such joint, summed over joints and frames, metres.</summary>
        public double DepthSum;
        /// <summary>The deepest, metres.</summary>
        public double MaxDepth;
    }

    /// <summary>One person of Motion.WriteGltf: a name (null: "person1", ...) and their own clip,
    /// Frames * 22 * 3 floats of t2m-22 positions.</summary>
    public sealed class PersonClip
    {
        /// <summary>The person's name, or null.</summary>
        public string Name;
        /// <summary>Positions, at least Frames * 66 floats.</summary>
        public float[] Positions;
        /// <summary>Frames of the clip, at least 1.</summary>
        public int Frames;
    }

    /// <summary>A whole clip retargeted onto a rig (Rig.RetargetClip): per frame, every rig
    /// joint's local rotation (w x y z, the rig's axes; Frames * Joints * 4 floats) and the
    /// moving joint's local translation (rig units and axes; Frames * 3 floats).</summary>
    public sealed class RigClip
    {
        /// <summary>Frames of the clip.</summary>
        public int Frames;
        /// <summary>Joints of the rig.</summary>
        public int Joints;
        /// <summary>Local rotations.</summary>
        public float[] Rotations;
        /// <summary>The moving joint's translations.</summary>
        public float[] RootTranslations;
        /// <summary>The moving joint.</summary>
        public int RootJoint;
    }

    /// <summary>The t2m-22 skeleton, joint positions to features and back, and files and
    /// pictures of people. Positions are float32 [frames][22][3] measured as a JointsFormat
    /// says. Thread-safe.</summary>
    public static class Motion
    {
        /// <summary>Joints of the t2m-22 skeleton (22).</summary>
        public static int JointCount { get { Native.CheckAbi(); return (int)Native.troupe_motion_joint_count(); } }

        /// <summary>The name of t2m-22 joint <paramref name="joint"/> ("pelvis", "left_hip", ...;
        /// SMPL's order), or null past the end.</summary>
        public static string JointName(int joint)
        {
            Native.CheckAbi();
            return joint < 0 ? null : Native.Utf8(Native.troupe_motion_joint_name((UIntPtr)joint));
        }

        /// <summary>Each joint's parent (-1 for the root; parents come before children).</summary>
        public static int[] Parents
        {
            get
            {
                Native.CheckAbi();
                var parents = new int[Native.Joints];
                Native.Check(Native.troupe_motion_skeleton(parents, (UIntPtr)parents.Length, null, UIntPtr.Zero));
                return parents;
            }
        }

        /// <summary>Each joint's rest offset from its parent, 22 * 3 floats (metres, Y up,
        /// facing +Z, +X the body's left; the root's is its rest position).</summary>
        public static float[] RestOffsets
        {
            get
            {
                Native.CheckAbi();
                var offsets = new float[Native.Joints * 3];
                Native.Check(Native.troupe_motion_skeleton(null, UIntPtr.Zero, offsets, (UIntPtr)offsets.Length));
                return offsets;
            }
        }

        /// <summary>MAGNet frames of one person (145 floats each) posed on the t2m-22 skeleton:
        /// frames * 22 * 3 positions (metres, Y up; troupe's neutral body).</summary>
        public static float[] Smplx145Positions(float[] frames, int count)
        {
            CheckFrames(frames, "frames", count, 145);
            Native.CheckAbi();
            var positions = new float[count * Native.Joints * 3];
            Native.Check(Native.troupe_motion_smplx145_positions(frames, (UIntPtr)count, positions, (UIntPtr)positions.Length));
            return positions;
        }

        /// <summary>How much two people's bodies (<paramref name="frames"/> frames of positions
        /// each, metres, Y up, one world) pass through each other.</summary>
        public static PenetrationMetrics Penetration(float[] first, float[] second, int frames)
        {
            CheckFrames(first, "first", frames, Native.Joints * 3);
            CheckFrames(second, "second", frames, Native.Joints * 3);
            Native.CheckAbi();
            UIntPtr n;
            var m = new PenetrationMetrics();
            Native.Check(Native.troupe_motion_penetration_metrics(first, second, (UIntPtr)frames, out n, out m.Frequency,
                out m.DepthSum, out m.MaxDepth));
            m.FramesIntersecting = (int)n;
            return m;
        }

        /// <summary>How many feature frames Encode gives for <paramref name="frames"/> frames
        /// measured as <paramref name="format"/> says (resampled to the model's rate, less one).</summary>
        public static int EncodedFrames(Model model, JointsFormat format, int frames)
        {
            if (model == null) throw new ArgumentNullException("model");
            if (frames < 0) throw new ArgumentOutOfRangeException("frames");
            var c = format.ToC();
            UIntPtr n;
            Native.Check(Native.troupe_motion_encoded_frames(model.Live(), ref c, (UIntPtr)frames, out n));
            return (int)n;
        }

        /// <summary>A clip of joint positions as <paramref name="model"/>'s feature frames
        /// (EncodedFrames * FrameDim floats), resampled and put in its canonical frame:
        /// InterGen's (floor under the lowest joint, origin and facing from frame 0), or
        /// <paramref name="given"/> (e.g. the first person's, for the second);
        /// <paramref name="placement"/> receives the one used.</summary>
        public static float[] Encode(Model model, JointsFormat format, float[] positions, int frames, out Placement placement,
                                     Placement? given = null)
        {
            if (model == null) throw new ArgumentNullException("model");
            CheckFrames(positions, "positions", frames, Native.Joints * 3);
            int n = EncodedFrames(model, format, frames);
            var c = format.ToC();
            var features = new float[n * model.FrameDim];
            UIntPtr written;
            Native.Check(Native.troupe_motion_encode(model.Live(), ref c, positions, (UIntPtr)frames,
                given.HasValue ? new[] { given.Value } : null, features, (UIntPtr)n, out written, out placement));
            if ((int)written != n) Array.Resize(ref features, (int)written * model.FrameDim);
            return features;
        }

        /// <summary><paramref name="frames"/> feature frames as poses in the caller's world
        /// (<paramref name="format"/>'s units and axes), put back with the
        /// <paramref name="placement"/> the motion was encoded with.</summary>
        public static Poses Decode(Model model, JointsFormat format, Placement placement, float[] features, int frames)
        {
            if (model == null) throw new ArgumentNullException("model");
            CheckFrames(features, "features", frames, model.FrameDim);
            var c = format.ToC();
            var poses = new Poses
            {
                Frames = frames,
                Positions = new float[frames * Native.Joints * 3],
                Rotations = new float[frames * Native.Joints * 4],
                Rotations6d = new float[frames * Native.Joints * 6],
                Contacts = new float[frames * 4],
            };
            using (var pins = new Native.Pins())
            {
                var buffers = new Native.PoseBuffersC
                {
                    positions = pins.Pin(poses.Positions), positions_len = (UIntPtr)poses.Positions.Length,
                    rotations = pins.Pin(poses.Rotations), rotations_len = (UIntPtr)poses.Rotations.Length,
                    rotations_6d = pins.Pin(poses.Rotations6d), rotations_6d_len = (UIntPtr)poses.Rotations6d.Length,
                    contacts = pins.Pin(poses.Contacts), contacts_len = (UIntPtr)poses.Contacts.Length,
                };
                Native.Check(Native.troupe_motion_decode(model.Live(), ref c, ref placement, features, (UIntPtr)frames, ref buffers));
            }
            return poses;
        }

        /// <summary>Writes people (names.Length of them; a null name is "person1", ...) on the
        /// t2m-22 skeleton as a BVH file: <paramref name="positions"/> holds people * frames *
        /// 22 * 3 floats as <paramref name="format"/> says (its Fps the file's rate);
        /// <paramref name="fitSkeleton"/> measures each person's bones from their motion.
        /// Written atomically; Take.Read reads it back.</summary>
        public static void WriteBvh(string path, string[] names, float[] positions, int frames, JointsFormat format,
                                    Units units = Units.Centimetres, bool fitSkeleton = true)
        {
            CheckPeople(path, names, positions, frames);
            var c = format.ToC();
            using (var pins = new Native.Pins())
                Native.Check(Native.troupe_bvh_write(Native.Utf8Z(path), positions, (UIntPtr)names.Length, (UIntPtr)frames,
                    ref c, Native.Utf8Array(names, pins), (uint)units, fitSkeleton ? 1u : 0u));
        }

        /// <summary>Writes people's poses (positions, rotations from inverse kinematics, foot
        /// contacts, the skeleton and the format) as a JSON document, atomically.</summary>
        public static void WriteJson(string path, string[] names, float[] positions, int frames, JointsFormat format)
        {
            CheckPeople(path, names, positions, frames);
            var c = format.ToC();
            using (var pins = new Native.Pins())
                Native.Check(Native.troupe_motion_write_json(Native.Utf8Z(path), positions, (UIntPtr)names.Length,
                    (UIntPtr)frames, ref c, Native.Utf8Array(names, pins)));
        }

        /// <summary>Writes pictures of people (1 to 8) moving: a self-contained HTML player at
        /// <paramref name="htmlPath"/> and an animated GIF at <paramref name="gifPath"/> (either
        /// may be null, not both), titled <paramref name="title"/> (null: none). Its Fps is the
        /// playback rate. Nothing is written on error.</summary>
        public static void WriteViewer(string htmlPath, string gifPath, string[] names, float[] positions, int frames,
                                       JointsFormat format, string title = null)
        {
            if (htmlPath == null && gifPath == null) throw new ArgumentNullException("htmlPath", "an HTML path, a GIF path or both");
            CheckPeople(htmlPath ?? gifPath, names, positions, frames);
            var c = format.ToC();
            using (var pins = new Native.Pins())
                Native.Check(Native.troupe_viewer_write(htmlPath == null ? null : Native.Utf8Z(htmlPath),
                    gifPath == null ? null : Native.Utf8Z(gifPath), positions, (UIntPtr)names.Length, (UIntPtr)frames, ref c,
                    Native.Utf8Array(names, pins), title == null ? null : Native.Utf8Z(title)));
        }

        /// <summary>Writes people of different lengths as one glTF binary file, retargeted onto
        /// <paramref name="rig"/> (null: troupe's own body); a shorter person holds their last
        /// pose to the end of the longest. <paramref name="flags"/>: RetargetFlags, NoBodies
        /// included.</summary>
        public static void WriteGltf(string path, PersonClip[] people, JointsFormat format, Rig rig = null,
                                     RetargetFlags flags = RetargetFlags.None)
        {
            if (path == null) throw new ArgumentNullException("path");
            if (people == null) throw new ArgumentNullException("people");
            var c = format.ToC();
            using (var pins = new Native.Pins())
            {
                var clips = new Native.PersonClipC[people.Length];
                for (int i = 0; i < people.Length; i++)
                {
                    PersonClip p = people[i];
                    if (p == null) throw new ArgumentNullException("people", "person " + i + " is null");
                    CheckFrames(p.Positions, "people[" + i + "].Positions", p.Frames, Native.Joints * 3);
                    clips[i] = new Native.PersonClipC { name = pins.Utf8(p.Name), positions = pins.Pin(p.Positions), n_frames = (UIntPtr)p.Frames };
                }
                byte[] utf8 = Native.Utf8Z(path);
                Native.CheckAbi();
                int status = rig == null
                    ? Native.troupe_gltf_write_people(utf8, IntPtr.Zero, clips, (UIntPtr)clips.Length, ref c, (uint)flags)
                    : Native.troupe_gltf_write_people(utf8, rig.Handle, clips, (UIntPtr)clips.Length, ref c, (uint)flags);
                Native.Check(status);
            }
        }

        private static void CheckPeople(string path, string[] names, float[] positions, int frames)
        {
            if (path == null) throw new ArgumentNullException("path");
            if (names == null) throw new ArgumentNullException("names");
            if (positions == null) throw new ArgumentNullException("positions");
            if (frames < 0 || (long)names.Length * frames * Native.Joints * 3 > positions.Length)
                throw new ArgumentException("positions holds fewer than " + names.Length + " people of " + frames + " frames", "positions");
            Native.CheckAbi();
        }

        internal static void CheckFrames(float[] data, string name, int frames, int floatsPerFrame)
        {
            if (data == null) throw new ArgumentNullException(name);
            if (frames < 0 || (long)frames * floatsPerFrame > data.Length)
                throw new ArgumentException(name + " holds " + data.Length + " floats, fewer than " + frames
                    + " frames of " + floatsPerFrame, name);
        }
    }

    /// <summary>One person's joint positions turned into a model's feature frames as they arrive
    /// (a session's actor input): feature frame t is ready when position frame t + 1 has
    /// arrived. One thread at a time; it does not need its model after creation.</summary>
    public sealed class MotionStream : IDisposable
    {
        private readonly MotionStreamHandle handle;
        private readonly int frameDim;

        /// <summary>A stream of <paramref name="model"/>'s features from positions measured as
        /// <paramref name="format"/> says; its canonical frame is fixed by the first frame
        /// unless <paramref name="placement"/> is given (e.g. another person's).</summary>
        public MotionStream(Model model, JointsFormat format, Placement? placement = null)
        {
            if (model == null) throw new ArgumentNullException("model");
            var c = format.ToC();
            Native.Check(Native.troupe_motion_stream_new(model.Live(), ref c, placement.HasValue ? new[] { placement.Value } : null,
                out handle));
            frameDim = model.FrameDim;
        }

        /// <summary>Frames of latency every stream adds (1).</summary>
        public static int LatencyFrames { get { Native.CheckAbi(); return (int)Native.troupe_motion_stream_latency_frames(); } }

        /// <summary>The most feature frames one Push writes (1 unless the caller's rate is above
        /// the model's): size Push's output with it.</summary>
        public int MaxFrames { get { return (int)Native.troupe_motion_stream_max_frames(Live()); } }

        /// <summary>Feeds one frame of positions (22 * 3 floats) and writes the feature frames it
        /// completes into <paramref name="features"/> (room for MaxFrames frames of FrameDim
        /// floats); returns how many (0 for the first frame). On error the stream is as it
        /// was.</summary>
        public int Push(float[] frame, float[] features)
        {
            if (frame == null) throw new ArgumentNullException("frame");
            if (frame.Length < Native.Joints * 3) throw new ArgumentException("frame holds fewer than 66 floats", "frame");
            if (features == null) throw new ArgumentNullException("features");
            UIntPtr written;
            Native.Check(Native.troupe_motion_stream_push(Live(), frame, (UIntPtr)(Native.Joints * 3), features,
                (UIntPtr)(features.Length / frameDim), out written));
            return (int)written;
        }

        /// <summary>The stream's placement (fixed by its first frame, or the one given); before
        /// either, InvalidArgumentException.</summary>
        public Placement Placement()
        {
            Placement p;
            Native.Check(Native.troupe_motion_stream_placement(Live(), out p));
            return p;
        }

        /// <summary>Forgets the motion and placement, as if new, or fixes the placement to
        /// <paramref name="placement"/>; a bad placement throws and leaves the stream as it was.</summary>
        public void Reset(Placement? placement = null)
        {
            Native.Check(Native.troupe_motion_stream_reset(Live(), placement.HasValue ? new[] { placement.Value } : null));
        }

        private bool disposed;

        private MotionStreamHandle Live()
        {
            if (disposed || handle.IsInvalid) throw new ObjectDisposedException("Troupe.MotionStream");
            return handle;
        }

        /// <summary>Frees the stream.</summary>
        public void Dispose()
        {
            disposed = true;
            handle.Dispose();
        }
    }

    /// <summary>Many sessions stepped at once.</summary>
    public static class Sessions
    {
        /// <summary>Advances sessions of one model in one call, reading the model's weights once
        /// per token for all of them (the way to run a crowd): session i gets
        /// <paramref name="actorFrames"/>[i] frames from <paramref name="actor"/>[i] (null when
        /// 0) and writes the frames that became ready into <paramref name="output"/>[i] (its
        /// length a multiple of FrameDim; null when none can be); returns how many each wrote.
        /// Each result equals what Session.Step gives that session alone (to 1e-5). The sessions
        /// must share one model and appear once each; on any error every session is as it was.
        /// No other thread may use them meanwhile.</summary>
        public static int[] Step(Session[] sessions, float[][] actor, int[] actorFrames, float[][] output)
        {
            if (sessions == null) throw new ArgumentNullException("sessions");
            if (actor == null) throw new ArgumentNullException("actor");
            if (actorFrames == null) throw new ArgumentNullException("actorFrames");
            if (output == null) throw new ArgumentNullException("output");
            int n = sessions.Length;
            if (actor.Length != n || actorFrames.Length != n || output.Length != n)
                throw new ArgumentException("sessions, actor, actorFrames and output differ in length");
            var handles = new SessionHandle[n];
            var added = new bool[n];
            var ptrs = new IntPtr[n];
            var actorPtrs = new IntPtr[n];
            var frames = new UIntPtr[n];
            var outPtrs = new IntPtr[n];
            var capacity = new UIntPtr[n];
            var written = new UIntPtr[n];
            using (var pins = new Native.Pins())
            {
                try
                {
                    for (int i = 0; i < n; i++)
                    {
                        if (sessions[i] == null) throw new ArgumentNullException("sessions", "session " + i + " is null");
                        int dim = sessions[i].FrameDim;
                        if (actorFrames[i] != 0 || actor[i] != null)
                            Session.CheckFrames(actor[i], "actor[" + i + "]", actorFrames[i], dim);
                        handles[i] = sessions[i].Handle();
                        handles[i].DangerousAddRef(ref added[i]);
                        ptrs[i] = handles[i].DangerousGetHandle();
                        actorPtrs[i] = pins.Pin(actor[i]);
                        frames[i] = (UIntPtr)actorFrames[i];
                        outPtrs[i] = pins.Pin(output[i]);
                        capacity[i] = (UIntPtr)(output[i] == null ? 0 : output[i].Length / dim);
                    }
                    Native.CheckAbi();
                    Native.Check(Native.troupe_sessions_step(ptrs, (UIntPtr)n, actorPtrs, frames, outPtrs, capacity, written));
                }
                finally
                {
                    for (int i = 0; i < n; i++) if (added[i]) handles[i].DangerousRelease();
                }
            }
            var counts = new int[n];
            for (int i = 0; i < n; i++) counts[i] = (int)written[i];
            return counts;
        }
    }

    /// <summary>What only an ARMFlow model offers, as Model.Armflow; its calls on another
    /// family's model throw UnsupportedException.</summary>
    public sealed class ArmflowModel
    {
        private readonly Model model;
        internal ArmflowModel(Model model) { this.model = model; }

        /// <summary>Tokens of the official clip (0 for a streaming-only bundle).</summary>
        public int ClipTokens { get { return (int)Native.troupe_armflow_clip_tokens(model.Live()); } }

        /// <summary>ARMFlow's official clip loop (Model.ArmflowClip).</summary>
        public float[] GenerateClip(float[] actor, int frames, float[] condition = null, ClipOptions options = null)
        {
            return model.ArmflowClip(actor, frames, condition, options);
        }

        /// <summary>An ARMFlow stream with the options every stream takes and ARMFlow's own
        /// (<paramref name="armflow"/>; null fields take the bundle's defaults). Other families
        /// throw UnsupportedException.</summary>
        public Session CreateSession(SessionOptions options = null, ArmflowSessionOptions armflow = null)
        {
            var h = model.Live();
            var opt = model.SessionOptionsC(options);
            var arm = new Native.ArmflowSessionOptionsC();
            Native.Check(Native.troupe_armflow_session_options_init(h, ref arm, Native.ArmflowSessionOptionsSize()));
            if (armflow != null)
            {
                if (armflow.CfgScale.HasValue) arm.cfg_scale = armflow.CfgScale.Value;
                if (armflow.ActorLatent.HasValue) arm.actor_latent = (int)armflow.ActorLatent.Value;
                if (armflow.VaeWindows.HasValue) arm.vae_windows = armflow.VaeWindows.Value ? 1 : 0;
            }
            SessionHandle session;
            Native.Check(Native.troupe_armflow_session_new(h, ref opt, ref arm, out session));
            session.HoldModel(h);
            return new Session(session, model.FrameDim);
        }
    }

    /// <summary>What only a UMF model offers, as Model.Umf: text to a group of any size. Its
    /// calls on another family's model throw UnsupportedException.</summary>
    public sealed class UmfModel
    {
        private readonly Model model;
        internal UmfModel(Model model) { this.model = model; }

        /// <summary>Pyramid stages of the bundle.</summary>
        public int Stages { get { return (int)Native.troupe_umf_stages(model.Live()); } }
        /// <summary>Latent tokens per person at full resolution.</summary>
        public int Tokens { get { return (int)Native.troupe_umf_tokens(model.Live()); } }

        /// <summary>How many standard normals a group of <paramref name="people"/> draws, by
        /// part: the lengths of UmfNoise's arrays.</summary>
        public void NoiseLengths(int people, out int prior, out int jumps, out int reactions)
        {
            if (people < 0) throw new ArgumentOutOfRangeException("people");
            UIntPtr p, j, r;
            Native.Check(Native.troupe_umf_noise_lengths(model.Live(), (uint)people, out p, out j, out r));
            prior = (int)p;
            jumps = (int)j;
            reactions = (int)r;
        }

        /// <summary>A group of <paramref name="people"/> for <paramref name="condition"/>
        /// (ConditionDim floats, e.g. Model.EncodePrompt's; null: the null condition): their
        /// motion, [people][ClipFrames][FrameDim] floats. Null <paramref name="noise"/> draws
        /// from the options' seed.</summary>
        public float[] GenerateGroup(float[] condition, int people, UmfOptions options = null, UmfNoise noise = null)
        {
            if (people < 1) throw new ArgumentOutOfRangeException("people", "a group has at least one person");
            var h = model.Live();
            var c = new Native.GroupOptionsC { stage_solver = new uint[Native.MaxStages], stage_steps = new uint[Native.MaxStages] };
            Native.Check(Native.troupe_umf_options_init(h, ref c, Native.GroupOptionsSize()));
            if (options != null)
            {
                c.seed = options.Seed;
                if (options.CfgScale.HasValue) c.cfg_scale = options.CfgScale.Value;
                if (options.ReactionSolver.HasValue) c.reaction_solver = (uint)options.ReactionSolver.Value;
                if (options.ReactionSteps.HasValue) c.reaction_steps = options.ReactionSteps.Value;
                if (options.StageSolvers != null)
                {
                    if (options.StageSolvers.Length != c.stage_count)
                        throw new ArgumentException("one solver per stage (" + c.stage_count + ")", "options");
                    for (int k = 0; k < options.StageSolvers.Length; k++) c.stage_solver[k] = (uint)options.StageSolvers[k];
                }
                if (options.StageSteps != null)
                {
                    if (options.StageSteps.Length != c.stage_count)
                        throw new ArgumentException("one step count per stage (" + c.stage_count + ")", "options");
                    Array.Copy(options.StageSteps, c.stage_steps, options.StageSteps.Length);
                }
            }
            long size = (long)people * model.ClipFrames * model.FrameDim;
            if (size > int.MaxValue) throw new ArgumentOutOfRangeException("people");
            var motion = new float[size];
            using (var pins = new Native.Pins())
            {
                Native.GroupNoiseC[] given = null;
                if (noise != null)
                {
                    given = new[] { new Native.GroupNoiseC
                    {
                        prior = pins.Pin(noise.Prior), prior_len = (UIntPtr)(noise.Prior == null ? 0 : noise.Prior.Length),
                        jumps = pins.Pin(noise.Jumps), jumps_len = (UIntPtr)(noise.Jumps == null ? 0 : noise.Jumps.Length),
                        reactions = pins.Pin(noise.Reactions), reactions_len = (UIntPtr)(noise.Reactions == null ? 0 : noise.Reactions.Length),
                    } };
                }
                Native.Check(Native.troupe_umf_generate(h, ref c, condition, (UIntPtr)(condition == null ? 0 : condition.Length),
                    (uint)people, given, motion, (UIntPtr)motion.Length, null, UIntPtr.Zero));
            }
            return motion;
        }
    }

    /// <summary>What only a MAGNet model offers, as Model.Magnet: the released tasks. Frames
    /// in and out are [frames][People][145] floats. Its calls on another family's model throw
    /// UnsupportedException.</summary>
    public sealed class MagnetModel
    {
        private readonly Model model;
        internal MagnetModel(Model model) { this.model = model; }

        /// <summary>People the model generates together (0 for another family).</summary>
        public int People { get { return (int)Native.troupe_magnet_people(model.Live()); } }

        /// <summary>The released sampling configurations ("dd100", "dd100_partner_prediction", ...).</summary>
        public IList<string> Configs
        {
            get
            {
                var h = model.Live();
                var names = new List<string>();
                ulong n = (ulong)Native.troupe_magnet_config_count(h);
                for (ulong i = 0; i < n; i++) names.Add(Native.Utf8(Native.troupe_magnet_config(h, (UIntPtr)i)));
                return names;
            }
        }

        /// <summary>The shape Generate returns for <paramref name="frameCount"/> input frames,
        /// with the same checks of the configuration and the input as the generation.</summary>
        public MagnetShape OutputShape(string config, int frameCount, MagnetOptions options = null)
        {
            if (config == null) throw new ArgumentNullException("config");
            if (frameCount < 0) throw new ArgumentOutOfRangeException("frameCount");
            var c = MagnetOptions.ToC(options);
            UIntPtr s, f, p;
            Native.Check(Native.troupe_magnet_output_shape(model.Live(), Native.Utf8Z(config), ref c, (UIntPtr)frameCount,
                out s, out f, out p));
            return new MagnetShape { Samples = (int)s, Frames = (int)f, People = (int)p };
        }

        /// <summary>Runs the sampling configuration <paramref name="config"/> (a released name or
        /// a whole configuration as JSON) on <paramref name="frameCount"/> frames and returns
        /// the frames it generates, OutputShape's [samples][frames][people][145] floats.
        /// <paramref name="present"/> (null: everyone) holds frameCount * People bytes, non-zero
        /// where the person is present.</summary>
        public float[] Generate(string config, float[] frames, int frameCount, MagnetOptions options = null, byte[] present = null)
        {
            int used;
            return Run(config, frames, frameCount, options, present, null, out used);
        }

        /// <summary>Generate with the run's standard normals given in <paramref name="draws"/>
        /// instead of drawn, in the order docs/MAGNET.md lists: how a recorded run of another
        /// implementation is reproduced. <paramref name="drawsUsed"/> receives how many it took;
        /// a run that needs more throws InvalidArgumentException.</summary>
        public float[] GenerateWithDraws(string config, float[] frames, int frameCount, float[] draws, out int drawsUsed,
                                         MagnetOptions options = null, byte[] present = null)
        {
            if (draws == null) throw new ArgumentNullException("draws");
            return Run(config, frames, frameCount, options, present, draws, out drawsUsed);
        }

        private float[] Run(string config, float[] frames, int frameCount, MagnetOptions options, byte[] present,
                            float[] draws, out int drawsUsed)
        {
            if (config == null) throw new ArgumentNullException("config");
            int people = People;
            Motion.CheckFrames(frames, "frames", frameCount, people * 145);
            if (present != null && present.Length < (long)frameCount * people)
                throw new ArgumentException("present holds fewer than " + frameCount + " * " + people + " bytes", "present");
            MagnetShape shape = OutputShape(config, frameCount, options);
            var c = MagnetOptions.ToC(options);
            long size = (long)shape.Samples * shape.Frames * shape.People * 145;
            if (size > int.MaxValue) throw new ArgumentOutOfRangeException("options", "the output would exceed an array");
            var output = new float[size];
            byte[] utf8 = Native.Utf8Z(config);
            if (draws == null)
            {
                drawsUsed = 0;
                Native.Check(Native.troupe_magnet_generate(model.Live(), utf8, ref c, frames, (UIntPtr)frameCount, present,
                    output, (UIntPtr)output.Length));
            }
            else
            {
                UIntPtr used;
                Native.Check(Native.troupe_magnet_generate_with_draws(model.Live(), utf8, ref c, frames, (UIntPtr)frameCount,
                    present, draws, (UIntPtr)draws.Length, out used, output, (UIntPtr)output.Length));
                drawsUsed = (int)used;
            }
            return output;
        }
    }

    /// <summary>What only an ARFlow model offers, as Model.Arflow; its calls on another
    /// family's model throw UnsupportedException.</summary>
    public sealed class ArflowModel
    {
        private readonly Model model;
        internal ArflowModel(Model model) { this.model = model; }

        /// <summary>ARFlow's whole reaction (Model.ArflowGenerate).</summary>
        public float[] Generate(float[] actor, int frames, ArflowOptions options = null)
        {
            return model.ArflowGenerate(actor, frames, options);
        }

        /// <summary>Generate with the run's standard normals given in <paramref name="draws"/>
        /// instead of drawn from the seed (the start noise when Sigma &gt; 0, then one ε per step
        /// when Eta &gt; 0, frames * 262 each); <paramref name="drawsUsed"/> receives how many
        /// it took; a run that needs more throws InvalidArgumentException.</summary>
        public float[] GenerateWithDraws(float[] actor, int frames, float[] draws, out int drawsUsed, ArflowOptions options = null)
        {
            if (draws == null) throw new ArgumentNullException("draws");
            Motion.CheckFrames(actor, "actor", frames, model.FrameDim);
            if (frames < 1) throw new ArgumentException("no actor frames", "frames");
            var h = model.Live();
            var c = ArflowOptions.ToC(h, options);
            var output = new float[frames * model.FrameDim];
            UIntPtr used;
            Native.Check(Native.troupe_arflow_generate_with_draws(h, ref c, actor, (UIntPtr)frames, draws, (UIntPtr)draws.Length,
                out used, output, (UIntPtr)frames));
            drawsUsed = (int)used;
            return output;
        }
    }

    /// <summary>What only an ARFlow online stream takes, as Session.Arflow.</summary>
    public sealed class ArflowSession
    {
        private readonly Session session;
        internal ArflowSession(Session session) { this.session = session; }

        /// <summary>The stream's sampler settings (null fields: the bundle's defaults), its
        /// seed too; a new step count only before the first frame or after Reset. Another
        /// family's stream throws UnsupportedException.</summary>
        public void SetOptions(ArflowOptions options)
        {
            if (options == null) throw new ArgumentNullException("options");
            SessionHandle h = session.Handle();
            var c = ArflowOptions.ToC(h.Model, options);
            Native.Check(Native.troupe_arflow_session_set_options(h, ref c));
        }
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

    /// <summary>A motion stream handle, freed once with troupe_motion_stream_free.</summary>
    public sealed class MotionStreamHandle : SafeHandle
    {
        /// <summary>An empty handle (the marshaller fills it).</summary>
        public MotionStreamHandle() : base(IntPtr.Zero, true) { }
        /// <summary>Whether the handle holds no stream.</summary>
        public override bool IsInvalid { get { return handle == IntPtr.Zero; } }
        /// <summary>Frees the stream.</summary>
        protected override bool ReleaseHandle() { Native.troupe_motion_stream_free(handle); return true; }
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

        /// <summary>Mirror of <c>troupe_session_options</c>.</summary>
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

        /// <summary>Mirror of <c>troupe_joints_format</c>.</summary>
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

        /// <summary>Mirror of <c>troupe_pose_buffers</c>.</summary>
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
        /// <summary>Mirror of <c>troupe_arflow_options</c>.</summary>
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

        /// <summary>Mirror of <c>troupe_armflow_clip_options</c>.</summary>
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

        // ---- limits, logging, progress, budgets, errors ----
        /// <summary>Mirror of <c>troupe_limits</c> (its <c>values</c> flattened).</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct LimitsC
        {
            public uint struct_size;
            public uint reserved;
            public ulong max_bundle_bytes;
            public ulong max_manifest_bytes;
            public ulong max_archive_members;
            public ulong max_graph_nodes;
            public ulong max_tensor_elements;
            public ulong max_steps;
            public ulong max_cfg_scale;
            public ulong max_abs_input;
            public ulong max_frames_per_call;
            public ulong max_queued_noise_tokens;
            public ulong max_context_capacity;
            public ulong max_people;
            public ulong max_text_tokens;
            public ulong max_manifest_dim;
            public ulong max_prompt_bytes;
            public ulong max_compute_threads;
        }

        /// <summary>Mirror of <c>troupe_call_budget</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct CallBudgetC
        {
            public ulong max_work;
            public double max_seconds;
        }

        [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
        internal delegate void LogFn(IntPtr userData, int level, IntPtr target, IntPtr message);
        [UnmanagedFunctionPointer(CallingConvention.Cdecl)]
        internal delegate int ProgressFn(IntPtr userData, ulong done, ulong total);

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_last_error_copy([Out] byte[] buf, UIntPtr capacity, out UIntPtr needed);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_limits_get(ref LimitsC limits, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_set_log_callback(LogFn callback, IntPtr userData, int maxLevel);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_set_progress_callback(ProgressFn callback, IntPtr userData);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_set_call_budget(ref CallBudgetC budget);

        // ---- model, session, text ----
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_reduced_precision_count(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_model_reduced_precision_graph(ModelHandle model, UIntPtr index);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_model_reduced_precision_weights(ModelHandle model, UIntPtr index);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_max_output_frames(ModelHandle model, UIntPtr actorFrames);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_condition_dim(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_session_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_sessions_step(IntPtr[] sessions, UIntPtr n, IntPtr[] actor, UIntPtr[] actorFrames, IntPtr[] output, UIntPtr[] capacityFrames, [Out] UIntPtr[] written);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_capabilities(SessionHandle session, out uint capabilities);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_queue_normals(SessionHandle session, [In] float[] normals, UIntPtr len);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_text_prompt_encode(ModelHandle model, byte[] prompt, [Out] float[] condition, UIntPtr capacity);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_model_text_token_dim(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_text_encode(ModelHandle model, [In] float[] tokens, UIntPtr nTokens, UIntPtr eotIndex, [Out] float[] condition, UIntPtr capacity);

        // ---- motion ----
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_motion_joint_count();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_motion_joint_name(UIntPtr joint);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_skeleton([Out] int[] parents, UIntPtr parentsLen, [Out] float[] restOffsets, UIntPtr restOffsetsLen);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_smplx145_positions([In] float[] frames, UIntPtr nFrames, [Out] float[] positions, UIntPtr positionsLen);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_penetration_metrics([In] float[] first, [In] float[] second, UIntPtr nFrames, out UIntPtr framesIntersecting, out double frequency, out double depthSum, out double maxDepth);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_encoded_frames(ModelHandle model, ref JointsFormatC format, UIntPtr nFrames, out UIntPtr framesOut);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_encode(ModelHandle model, ref JointsFormatC format, [In] float[] positions, UIntPtr nFrames, [In] Placement[] placement, [Out] float[] features, UIntPtr capacityFrames, out UIntPtr written, out Placement placementOut);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_decode(ModelHandle model, ref JointsFormatC format, ref Placement placement, [In] float[] features, UIntPtr nFrames, ref PoseBuffersC output);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_stream_new(ModelHandle model, ref JointsFormatC format, [In] Placement[] placement, out MotionStreamHandle stream);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_motion_stream_latency_frames();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_motion_stream_max_frames(MotionStreamHandle stream);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_stream_push(MotionStreamHandle stream, [In] float[] frame, UIntPtr frameLen, [Out] float[] features, UIntPtr capacityFrames, out UIntPtr written);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_stream_placement(MotionStreamHandle stream, out Placement placement);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_stream_reset(MotionStreamHandle stream, [In] Placement[] placement);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern void troupe_motion_stream_free(IntPtr stream);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_bvh_write(byte[] path, [In] float[] positions, UIntPtr people, UIntPtr frames, ref JointsFormatC format, IntPtr[] names, uint units, uint fitSkeleton);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_motion_write_json(byte[] path, [In] float[] positions, UIntPtr people, UIntPtr frames, ref JointsFormatC format, IntPtr[] names);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_viewer_write(byte[] htmlPath, byte[] gifPath, [In] float[] positions, UIntPtr people, UIntPtr frames, ref JointsFormatC format, IntPtr[] names, byte[] title);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_session_joints_placement(SessionHandle session, out Placement placement);

        /// <summary>Mirror of <c>troupe_person_clip</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct PersonClipC
        {
            public IntPtr name;
            public IntPtr positions;
            public UIntPtr n_frames;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_rig_retarget_clip(RigHandle rig, [In] float[] positions, UIntPtr nFrames, ref JointsFormatC format, uint flags, [Out] float[] rotations, UIntPtr rotationsLen, [Out] float[] rootTranslations, UIntPtr rootLen, out UIntPtr rootJoint);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_gltf_write_people(byte[] path, RigHandle rig, [In] PersonClipC[] people, UIntPtr nPeople, ref JointsFormatC format, uint flags);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_gltf_write_people(byte[] path, IntPtr noRig, [In] PersonClipC[] people, UIntPtr nPeople, ref JointsFormatC format, uint flags);

        // ---- ARMFlow ----
        /// <summary>Mirror of <c>troupe_armflow_session_options</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct ArmflowSessionOptionsC
        {
            public uint struct_size;
            public float cfg_scale;
            public int actor_latent;
            public int vae_windows;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_armflow_clip_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_armflow_clip_tokens(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_session_queue_noise(SessionHandle session, [In] float[] actorNoise, [In] float[] reactorNoise, UIntPtr len);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_armflow_session_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_session_options_init(ModelHandle model, ref ArmflowSessionOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_armflow_session_new(ModelHandle model, ref SessionOptionsC options, ref ArmflowSessionOptionsC armflow, out SessionHandle session);

        // ---- UMF ----
        internal const int MaxStages = 8;

        /// <summary>Mirror of <c>troupe_group_options</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct GroupOptionsC
        {
            public uint struct_size;
            public uint stage_count;
            public ulong seed;
            public float cfg_scale;
            public uint reaction_solver;
            public uint reaction_steps;
            public uint reserved;
            [MarshalAs(UnmanagedType.ByValArray, SizeConst = MaxStages)] public uint[] stage_solver;
            [MarshalAs(UnmanagedType.ByValArray, SizeConst = MaxStages)] public uint[] stage_steps;
        }

        /// <summary>Mirror of <c>troupe_group_noise</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct GroupNoiseC
        {
            public IntPtr prior;
            public UIntPtr prior_len;
            public IntPtr jumps;
            public UIntPtr jumps_len;
            public IntPtr reactions;
            public UIntPtr reactions_len;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_umf_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_umf_options_init(ModelHandle model, ref GroupOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_umf_stages(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_umf_tokens(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_umf_noise_lengths(ModelHandle model, uint people, out UIntPtr priorLen, out UIntPtr jumpsLen, out UIntPtr reactionsLen);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_umf_generate(ModelHandle model, ref GroupOptionsC options, [In] float[] condition, UIntPtr conditionLen, uint people, [In] GroupNoiseC[] noise, [Out] float[] motion, UIntPtr motionCapacity, [Out] float[] latents, UIntPtr latentsCapacity);

        // ---- MAGNet ----
        internal const int MaxKeyframes = 8;

        /// <summary>Mirror of <c>troupe_magnet_options</c>.</summary>
        [StructLayout(LayoutKind.Sequential)]
        internal struct MagnetOptionsC
        {
            public uint struct_size;
            public uint samples;
            public uint steps;
            public uint seq_len;
            public uint flags;
            public uint keyframe_count;
            public ulong seed;
            public float eta;
            public uint reserved;
            [MarshalAs(UnmanagedType.ByValArray, SizeConst = MaxKeyframes)] public uint[] keyframes;
        }

        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_magnet_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_options_init(ref MagnetOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_magnet_people(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_magnet_config_count(ModelHandle model);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern IntPtr troupe_magnet_config(ModelHandle model, UIntPtr index);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_output_shape(ModelHandle model, byte[] config, ref MagnetOptionsC options, UIntPtr frameCount, out UIntPtr samples, out UIntPtr frames, out UIntPtr people);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_generate(ModelHandle model, byte[] config, ref MagnetOptionsC options, [In] float[] frames, UIntPtr frameCount, [In] byte[] present, [Out] float[] output, UIntPtr capacity);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_magnet_generate_with_draws(ModelHandle model, byte[] config, ref MagnetOptionsC options, [In] float[] frames, UIntPtr frameCount, [In] byte[] present, [In] float[] draws, UIntPtr drawsLen, out UIntPtr drawsUsed, [Out] float[] output, UIntPtr capacity);

        // ---- ARFlow ----
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern UIntPtr troupe_arflow_options_size();
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_arflow_options_init(IntPtr model, ref ArflowOptionsC options, UIntPtr size);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_arflow_generate_with_draws(ModelHandle model, ref ArflowOptionsC options, [In] float[] actor, UIntPtr frames, [In] float[] draws, UIntPtr drawsLen, out UIntPtr drawsUsed, [Out] float[] output, UIntPtr capacityFrames);
        [DllImport(Lib, CallingConvention = CallingConvention.Cdecl)] internal static extern int troupe_arflow_session_set_options(SessionHandle session, ref ArflowOptionsC options);

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
            if (status == 0) return;
            Exception thrown = Library.TakeProgressException();
            throw TroupeException.FromStatus(status, LastError(), status == 11 ? thrown : null);
        }

        /// <summary>This thread's last error message, copied by the library into a managed
        /// buffer (troupe_last_error_copy, which does not clear it).</summary>
        internal static string LastError()
        {
            UIntPtr needed;
            if (troupe_last_error_copy(null, UIntPtr.Zero, out needed) != 0)
                return Utf8(troupe_last_error_message()) ?? "";
            var buf = new byte[(int)needed];
            if (troupe_last_error_copy(buf, needed, out needed) != 0) return "";
            int n = Array.IndexOf(buf, (byte)0);
            return Encoding.UTF8.GetString(buf, 0, n < 0 ? buf.Length : n);
        }

        private static readonly HashSet<Type> mirrorsChecked = new HashSet<Type>();

        /// <summary>The size of the C struct mirror <paramref name="mirror"/>, once checked against
        /// the library's own <paramref name="librarySize"/> (a troupe_*_options_size function).
        /// Fields are only ever appended (docs/ABI.md): a newer library, whose struct is larger,
        /// reads this one as the older version it is; an older library, whose struct is smaller,
        /// lacks fields this binding fills and is refused before any call reads the struct.</summary>
        internal static UIntPtr Mirror(Type mirror, Func<UIntPtr> librarySize, string cName)
        {
            int mine = Marshal.SizeOf(mirror);
            lock (mirrorsChecked)
            {
                if (!mirrorsChecked.Contains(mirror))
                {
                    CheckAbi();
                    ulong theirs = (ulong)librarySize();
                    if (theirs < (ulong)mine)
                        throw new TroupeException(-1, "TROUPE_ERR_UNKNOWN", cName + " is " + theirs
                            + " bytes in the native library and " + mine + " in this binding: the library is"
                            + " older than this Troupe.cs; use the library's release or a newer one");
                    mirrorsChecked.Add(mirror);
                }
            }
            return (UIntPtr)mine;
        }

        internal static UIntPtr SessionOptionsSize() { return Mirror(typeof(SessionOptionsC), troupe_session_options_size, "troupe_session_options"); }
        internal static UIntPtr ClipOptionsSize() { return Mirror(typeof(ClipOptionsC), troupe_armflow_clip_options_size, "troupe_armflow_clip_options"); }
        internal static UIntPtr ArmflowSessionOptionsSize() { return Mirror(typeof(ArmflowSessionOptionsC), troupe_armflow_session_options_size, "troupe_armflow_session_options"); }
        internal static UIntPtr GroupOptionsSize() { return Mirror(typeof(GroupOptionsC), troupe_umf_options_size, "troupe_group_options"); }
        internal static UIntPtr MagnetOptionsSize() { return Mirror(typeof(MagnetOptionsC), troupe_magnet_options_size, "troupe_magnet_options"); }
        internal static UIntPtr ArflowOptionsSize() { return Mirror(typeof(ArflowOptionsC), troupe_arflow_options_size, "troupe_arflow_options"); }

        /// <summary>NUL-terminated UTF-8 copies of <paramref name="names"/> in native memory
        /// (IntPtr.Zero for a null entry), freed with <paramref name="pins"/>.</summary>
        internal static IntPtr[] Utf8Array(string[] names, Pins pins)
        {
            var utf8 = new IntPtr[names.Length];
            for (int i = 0; i < names.Length; i++) utf8[i] = pins.Utf8(names[i]);
            return utf8;
        }

        /// <summary>Arrays pinned and strings copied to native memory for the length of one call;
        /// Dispose lets go of them all.</summary>
        internal sealed class Pins : IDisposable
        {
            private readonly List<GCHandle> handles = new List<GCHandle>();
            private readonly List<IntPtr> strings = new List<IntPtr>();

            /// <summary>The address of <paramref name="array"/>'s first element, pinned (IntPtr.Zero for null).</summary>
            internal IntPtr Pin(Array array)
            {
                if (array == null) return IntPtr.Zero;
                var h = GCHandle.Alloc(array, GCHandleType.Pinned);
                handles.Add(h);
                return h.AddrOfPinnedObject();
            }

            /// <summary>A NUL-terminated UTF-8 copy of <paramref name="s"/> in native memory (IntPtr.Zero for null).</summary>
            internal IntPtr Utf8(string s)
            {
                if (s == null) return IntPtr.Zero;
                byte[] bytes = Utf8Z(s);
                IntPtr p = Marshal.AllocHGlobal(bytes.Length);
                strings.Add(p);
                Marshal.Copy(bytes, 0, p, bytes.Length);
                return p;
            }

            /// <summary>Unpins and frees everything.</summary>
            public void Dispose()
            {
                foreach (GCHandle h in handles) h.Free();
                foreach (IntPtr p in strings) Marshal.FreeHGlobal(p);
                handles.Clear();
                strings.Clear();
            }
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

#if !UNITY_5_3_OR_NEWER
namespace AOT
{
    /// <summary>Marks a static method native code calls back, as Unity's IL2CPP needs (Unity
    /// defines this attribute itself; elsewhere it is this one, which changes nothing).</summary>
    [AttributeUsage(AttributeTargets.Method)]
    internal sealed class MonoPInvokeCallbackAttribute : Attribute
    {
        /// <summary>Marks a method called through a delegate of <paramref name="type"/>.</summary>
        public MonoPInvokeCallbackAttribute(Type type) { DelegateType = type; }
        /// <summary>The delegate type native code calls the method through.</summary>
        public Type DelegateType { get; private set; }
    }
}
#endif
